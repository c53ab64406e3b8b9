//! The fixed-point program: the IR with its format plan ([`FixedProgram`]), and what the
//! plan's users read from it (exact constants, declared states in SI, the products' forms).
//! The plan is made in [`super::plan`]; the program is plain data afterwards, which every
//! fixed engine and backend runs.

use super::*;

/// The Q-format name of a fraction-bit count: `Q{31−frac}.{frac}` (sign bit not counted).
pub fn q_name(frac: i32) -> String {
    format!("Q{}.{}", 31 - frac, frac)
}

/// The finest format holding `iv` in an `i32`: fraction bits ([`tactus_runtime::fixed::frac_for`]).
pub fn frac_for(iv: Interval) -> i32 {
    tactus_runtime::fixed::frac_for(iv.mag())
}

/// A program compiled to fixed point.
#[derive(Clone, Debug)]
pub struct FixedProgram {
    /// The IR (its statement list is what every fixed engine executes).
    pub program: Program,
    /// Interval of every value.
    pub ranges: Ranges,
    /// Fraction bits of every value (truth values and modes: 0).
    pub frac: Vec<i32>,
    /// Raw word of every constant and param value (0 for other values).
    pub consts: Vec<i32>,
    /// For a division by a constant: the raw word and fraction bits of the reciprocal it
    /// multiplies by instead.
    pub recip: Vec<Option<(i32, i32)>>,
    /// How each multiplication (and division by a constant) is done; `None` for other values.
    pub mul_kind: Vec<Option<MulKind>>,
    /// Per product: the cheaper forms the planner considered beside the exact 64-bit one, in
    /// the order tried (its `MULS` plan when the operands can be pre-shifted into 32 bits,
    /// its high word when the partial sum fits); empty for other values.
    pub mul_options: Vec<Vec<MulKind>>,
    /// For a division by a run-time value: the right shift of its divisor's word
    /// ([`tactus_runtime::fixed::div_shifted`]); 0 for an exact division and for other values.
    pub div_shift: Vec<u8>,
    /// Fraction bits of each sensor (from its declared range).
    pub sensor_frac: Vec<i32>,
    /// Raw bounds of each sensor.
    pub sensor_raw_range: Vec<(i32, i32)>,
    /// Fraction bits of each state (from its declared range).
    pub state_frac: Vec<i32>,
    /// Raw bounds each state write saturates to.
    pub state_raw_range: Vec<(i32, i32)>,
    /// Raw initial value of each state.
    pub state_init: Vec<i32>,
    /// `fs/N` and `(fs/N)²` of the differentiators as (raw, fraction bits).
    pub deriv_gain: [(i32, i32); 2],
    /// Format of each force term (that of its value).
    pub force_frac: Vec<i32>,
    /// Format of the total force.
    pub total_frac: i32,
    /// Format of each output.
    pub output_frac: Vec<i32>,
    /// Format of each event argument: the coarsest among the emits of that event; `emit`
    /// converts its arguments to it.
    pub event_frac: Vec<Vec<i32>>,
    /// Saturation inserted where the analysis found no bound.
    pub warnings: Vec<Diagnostic>,
    /// Per param ([`ParamId`]): its word's index in a key's param block when it is a
    /// run-time param ([`ParamDecl::runtime`]), else `None`.
    pub param_slot: Vec<Option<usize>>,
    /// Per word of the param block ([`Program::runtime_params`] order): its fraction bits
    /// (those of every value reading it) and the raw bounds of its declared interval.
    pub param_words: Vec<ParamWord>,
    /// The states whose divisions became products with a hidden reciprocal state
    /// ([`recip`]); the hidden states are the last `reciprocals.len()` of
    /// `program.states`, in this order.
    pub reciprocals: Vec<recip::Reciprocal>,
    /// States used as divisors that keep their divisions, and why ([`recip::Refused`]).
    pub refused_reciprocals: Vec<recip::Refused>,
    /// Per state of `program`: its declared range when the plan narrowed it to the hull of
    /// what the state is assigned ([`range::state_hulls`]; `program.states` holds the hull,
    /// which its word's format, its saturation and every read's interval follow), else
    /// `None`.
    pub narrowed: Vec<Option<(f64, f64)>>,
}

/// The format of one word of a key's param block.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct ParamWord {
    /// The run-time param it holds.
    pub param: ParamId,
    /// Fraction bits.
    pub frac: i32,
    /// Raw bounds: the words of the param's interval ends in this format.
    pub raw_range: (i32, i32),
}

/// Formats of what the body publishes.
pub(super) struct Published {
    pub(super) force: Vec<i32>,
    pub(super) total: i32,
    pub(super) output: Vec<i32>,
    pub(super) event: Vec<Vec<i32>>,
}

pub(super) fn published(p: &Program, frac: &[i32]) -> Published {
    let mut out = Published {
        force: vec![0; p.forces.len()],
        total: 0,
        output: vec![0; p.outputs.len()],
        event: p
            .events
            .iter()
            .map(|e| vec![FRAC_RANGE.1; e.args.len()])
            .collect(),
    };
    fn walk(stmts: &[Stmt], frac: &[i32], out: &mut Published) {
        for s in stmts {
            match s {
                Stmt::Force(f, v) => out.force[f.index()] = frac[v.index()],
                Stmt::Total(v) => out.total = frac[v.index()],
                Stmt::Output(o, v) => out.output[o.index()] = frac[v.index()],
                Stmt::Emit(e, args) => {
                    for (slot, v) in out.event[e.index()].iter_mut().zip(args) {
                        *slot = (*slot).min(frac[v.index()]);
                    }
                }
                Stmt::If(_, body) => walk(body, frac, out),
                _ => {}
            }
        }
    }
    walk(&p.body, frac, &mut out);
    out
}

pub(super) fn constant(v: f64) -> (i32, i32) {
    let f = frac_for(Interval::point(v));
    (fx::from_f64(v, f).0, f)
}

impl FixedProgram {
    /// The exact (unquantised) value of a constant or compile-time param value, for
    /// comparisons; `None` for a run-time param and every other value.
    pub fn exact_const(&self, v: Value) -> Option<f64> {
        self.program.const_value(v)
    }

    /// Number of declared states: those of the source program, before the hidden reciprocal
    /// states ([`FixedProgram::reciprocals`]).
    pub fn declared_states(&self) -> usize {
        self.program.states.len() - self.reciprocals.len()
    }

    /// The declared states' values (SI) from a fixed engine's state words (all of them,
    /// hidden ones included): each word in its format, except that a state carried by its
    /// reciprocal ([`recip::Reciprocal::carried`]: the fixed program no longer writes it) is
    /// `k / (k/s)` of its hidden word (`k` its [`recip::Reciprocal::scale`]). What traces of
    /// the fixed engines show.
    pub fn states_si(&self, words: &[i32]) -> Vec<f64> {
        let n = self.declared_states().min(words.len());
        let mut out: Vec<f64> = (0..n)
            .map(|i| fx::to_f64(words[i], self.state_frac[i]))
            .collect();
        for r in self.reciprocals.iter().filter(|r| r.carried) {
            let (s, h) = (r.state.index(), r.recip.index());
            if s < n && h < words.len() {
                out[s] = r.scale / fx::to_f64(words[h], self.state_frac[h]);
            }
        }
        out
    }

    /// Saturations per declared state from a fixed engine's counts per state (hidden ones
    /// included): a state carried by its reciprocal counts its reciprocal's (the
    /// reciprocal saturates exactly when the state would: [`recip`]).
    pub fn declared_saturations(&self, counts: &[u64]) -> Vec<u64> {
        let n = self.declared_states().min(counts.len());
        let mut out = counts[..n].to_vec();
        for r in self.reciprocals.iter().filter(|r| r.carried) {
            if let Some(&c) = counts.get(r.recip.index()) {
                if r.state.index() < n {
                    out[r.state.index()] = c;
                }
            }
        }
        out
    }

    /// Number of multiplications of each form and their estimated cycles on a Cortex-M0+
    /// ([`MulKind::cycles`]).
    pub fn mul_forms(&self) -> MulForms {
        let mut f = MulForms::default();
        for k in self.mul_kind.iter().flatten() {
            match k {
                MulKind::Muls(..) => f.muls += 1,
                MulKind::Mul32x16 { .. } => f.m32x16 += 1,
                MulKind::High(_) => f.high += 1,
                MulKind::Wide => f.wide += 1,
            }
            f.cycles += k.cycles();
        }
        f
    }

    /// Number of `MULS` products, of products needing more (32×16, high word or 64-bit),
    /// and the estimated cycles of all ([`FixedProgram::mul_forms`]).
    pub fn mul_cost(&self) -> (usize, usize, u32) {
        let f = self.mul_forms();
        (f.muls, f.m32x16 + f.high + f.wide, f.cycles)
    }
}
