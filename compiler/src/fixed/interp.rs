//! The fixed-point interpreter: the definition of the bits.
//!
//! It executes the same statement list as the f64 reference interpreter, on raw 32-bit
//! words in the formats of the [`FixedProgram`], with every operation computed by
//! [`tactus_runtime::fixed`]. The JIT, the Thumb code and the C code must reproduce its
//! output bit for bit. In overflow-detecting mode it records every value whose computation
//! saturated, so tests can check the range analysis's claim that nothing else ever does.

use super::FixedProgram;
use crate::ir::*;
use tactus_runtime::differentiator::RawHistory;
use tactus_runtime::fixed as fx;

/// What one sample produced, as raw words: forces in [`FixedProgram::force_frac`], the total
/// in [`FixedProgram::total_frac`], outputs in [`FixedProgram::output_frac`], event
/// arguments in [`FixedProgram::event_frac`].
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct RawOut {
    /// Each force term, in its value's format.
    pub forces: Vec<i32>,
    /// The total force, in its value's format.
    pub total: i32,
    /// Each output.
    pub outputs: Vec<i32>,
    /// Events emitted this sample with their raw arguments.
    pub events: Vec<(EventId, Vec<i32>)>,
}

/// One running fixed-point instance (one key).
#[derive(Clone, Debug)]
pub struct FixedInstance<'f> {
    fp: &'f FixedProgram,
    states: Vec<i32>,
    modes: Vec<u32>,
    edges: Vec<bool>,
    sensors: Vec<i32>,
    /// Buffer for [`FixedInstance::step`]'s converted readings.
    input: Vec<i32>,
    hist: Vec<RawHistory>,
    vals: Vec<i32>,
    overflowed: Vec<bool>,
    saturations: Vec<u64>,
    out: RawOut,
    /// The key's param block ([`FixedProgram::param_block`]).
    params: Vec<i32>,
}

impl<'f> FixedInstance<'f> {
    /// A fresh instance at the initial state, with the params' own values
    /// ([`FixedProgram::nominal_param_block`]).
    pub fn new(fp: &'f FixedProgram) -> Self {
        Self::with_params(fp, fp.nominal_param_block())
    }

    /// A fresh instance of one key of a shared program: `params` is the key's param block
    /// ([`FixedProgram::param_block`]; a missing word reads as 0).
    pub fn with_params(fp: &'f FixedProgram, params: Vec<i32>) -> Self {
        let p = &fp.program;
        FixedInstance {
            params,
            fp,
            states: fp.state_init.clone(),
            modes: p.modes.iter().map(|m| m.init).collect(),
            edges: vec![false; p.edges.len()],
            sensors: vec![0; p.sensors.len()],
            input: Vec::with_capacity(p.sensors.len()),
            hist: vec![RawHistory::default(); p.sensors.len()],
            vals: vec![0; p.values.len()],
            overflowed: vec![false; p.values.len()],
            saturations: vec![0; p.states.len()],
            out: RawOut {
                forces: vec![0; p.forces.len()],
                outputs: vec![0; p.outputs.len()],
                ..RawOut::default()
            },
        }
    }

    /// Converts sensor readings (SI) to raw words: saturated to the declared range, then
    /// rounded half up in the sensor's format (NaN or missing → lower bound). Every engine
    /// uses this conversion.
    pub fn sensor_raw(fp: &FixedProgram, i: usize, x: Option<f64>) -> i32 {
        let s = &fp.program.sensors[i];
        let x = match x {
            Some(x) if !x.is_nan() => x.clamp(s.range.0, s.range.1),
            _ => s.range.0,
        };
        let (lo, hi) = fp.sensor_raw_range[i];
        fx::from_f64(x, fp.sensor_frac[i]).0.clamp(lo, hi)
    }

    /// Runs one sample on SI sensor readings.
    pub fn step(&mut self, sensors: &[f64]) -> &RawOut {
        // Converted into a buffer kept for the purpose: no allocation per sample.
        let mut raw = std::mem::take(&mut self.input);
        raw.clear();
        raw.extend(
            (0..self.fp.program.sensors.len())
                .map(|i| Self::sensor_raw(self.fp, i, sensors.get(i).copied())),
        );
        self.step_raw(&raw);
        self.input = raw;
        &self.out
    }

    /// Runs one sample on raw sensor words (already in the sensors' formats and ranges).
    pub fn step_raw(&mut self, sensors: &[i32]) -> &RawOut {
        for (i, s) in self.fp.program.sensors.iter().enumerate() {
            let (lo, hi) = self.fp.sensor_raw_range[i];
            let x = sensors.get(i).copied().unwrap_or(lo).clamp(lo, hi);
            self.sensors[i] = x;
            if s.differentiated {
                self.hist[i].push(x);
            }
        }
        self.out.events.clear();
        let body = &self.fp.program.body;
        self.exec(body);
        &self.out
    }

    fn exec(&mut self, stmts: &[Stmt]) {
        for s in stmts {
            match s {
                Stmt::Def(v) => {
                    let (x, o) = self.eval(*v);
                    self.vals[v.index()] = x;
                    if o {
                        self.overflowed[v.index()] = true;
                    }
                }
                Stmt::SetState(st, v) => {
                    let i = st.index();
                    let (x, _) = fx::convert(
                        self.vals[v.index()],
                        self.fp.frac[v.index()],
                        self.fp.state_frac[i],
                    );
                    let (lo, hi) = self.fp.state_raw_range[i];
                    let y = x.clamp(lo, hi);
                    if y != x {
                        self.saturations[i] += 1;
                    }
                    self.states[i] = y;
                }
                Stmt::SetMode(m, i) => self.modes[m.index()] = *i,
                Stmt::SetEdge(e, v) => self.edges[e.index()] = self.vals[v.index()] != 0,
                Stmt::If(c, body) => {
                    if self.vals[c.index()] != 0 {
                        self.exec(body);
                    }
                }
                Stmt::Emit(e, args) => {
                    let formats = &self.fp.event_frac[e.index()];
                    let a = args
                        .iter()
                        .zip(formats)
                        .map(|(v, &f)| {
                            fx::convert(self.vals[v.index()], self.fp.frac[v.index()], f).0
                        })
                        .collect();
                    self.out.events.push((*e, a));
                }
                Stmt::Force(f, v) => self.out.forces[f.index()] = self.vals[v.index()],
                Stmt::Output(o, v) => self.out.outputs[o.index()] = self.vals[v.index()],
                Stmt::Total(v) => self.out.total = self.vals[v.index()],
            }
        }
    }

    fn eval(&self, v: Value) -> fx::Sat {
        let fp = self.fp;
        let p = &fp.program;
        let fr = fp.frac[v.index()];
        let val = |x: &Value| (self.vals[x.index()], fp.frac[x.index()]);
        let b = |t: bool| (i32::from(t), false);
        match &p.values[v.index()].op {
            Op::Param(p) if fp.param_slot[p.index()].is_some() => {
                let k = fp.param_slot[p.index()].unwrap_or(0);
                (self.params.get(k).copied().unwrap_or(0), false)
            }
            Op::Const(_) | Op::Param(_) => (fp.consts[v.index()], false),
            Op::BoolConst(t) => b(*t),
            Op::Variant(_, i) => (*i as i32, false),
            Op::Sensor(s) => fx::convert(self.sensors[s.index()], fp.sensor_frac[s.index()], fr),
            Op::Deriv(s, order) => {
                let h = &self.hist[s.index()];
                let d = if *order == 1 { h.diff1() } else { h.diff2() };
                let (k, fk) = fp.deriv_gain[(*order as usize).saturating_sub(1).min(1)];
                fx::sat32(fx::rescale(
                    d as i128 * k as i128,
                    fp.sensor_frac[s.index()] + fk,
                    fr,
                ))
            }
            Op::State(s) => fx::convert(self.states[s.index()], fp.state_frac[s.index()], fr),
            Op::Mode(m) => (self.modes[m.index()] as i32, false),
            Op::Edge(e) => b(self.edges[e.index()]),
            Op::Neg(x) => {
                let (x, f) = val(x);
                fx::neg(x, f, fr)
            }
            Op::Not(x) => b(self.vals[x.index()] == 0),
            Op::Arith(o, x, y) => {
                let ((a, fa), (c, fc)) = (val(x), val(y));
                match o {
                    ArithOp::Add => fx::add(a, fa, c, fc, fr),
                    ArithOp::Sub => fx::sub(a, fa, c, fc, fr),
                    ArithOp::Mul => product(fp.mul_kind[v.index()], (a, fa), (c, fc), fr),
                    ArithOp::Div => match fp.recip[v.index()] {
                        // A division by a constant: the product by its reciprocal word.
                        Some(r) => product(fp.mul_kind[v.index()], (a, fa), r, fr),
                        None => fx::div_shifted(a, fa, c, fc, fp.div_shift[v.index()], fr),
                    },
                }
            }
            Op::Cmp(o, x, y) => {
                let ((a, fa), (c, fc)) = (val(x), val(y));
                let real = |w: &Value| matches!(p.values[w.index()].ty, Ty::Real(_));
                let ord = match (fp.exact_const(*x), fp.exact_const(*y)) {
                    (_, Some(k)) if real(x) => fx::cmp_const(a, fa, k),
                    (Some(k), _) if real(y) => fx::cmp_const(c, fc, k).reverse(),
                    _ => fx::cmp(a, fa, c, fc),
                };
                use std::cmp::Ordering::*;
                b(match o {
                    CmpOp::Eq => ord == Equal,
                    CmpOp::Ne => ord != Equal,
                    CmpOp::Lt => ord == Less,
                    CmpOp::Le => ord != Greater,
                    CmpOp::Gt => ord == Greater,
                    CmpOp::Ge => ord != Less,
                })
            }
            Op::And(x, y) => b(self.vals[x.index()] != 0 && self.vals[y.index()] != 0),
            Op::Or(x, y) => b(self.vals[x.index()] != 0 || self.vals[y.index()] != 0),
            Op::Select(c, x, y) => {
                let (a, f) = if self.vals[c.index()] != 0 {
                    val(x)
                } else {
                    val(y)
                };
                match p.values[v.index()].ty {
                    Ty::Real(_) => fx::convert(a, f, fr),
                    _ => (a, false),
                }
            }
            Op::Call(func, x, y) => {
                let (a, fa) = val(x);
                match func {
                    Builtin::Abs => {
                        if a < 0 {
                            fx::neg(a, fa, fr)
                        } else {
                            fx::convert(a, fa, fr)
                        }
                    }
                    Builtin::Sqrt => fx::sqrt(a, fa, fr),
                    Builtin::Exp => fx::exp(a, fa, fr),
                    Builtin::Min | Builtin::Max => {
                        let (c, fc) = y.map(|y| val(&y)).unwrap_or((a, fa));
                        let less = fx::cmp(a, fa, c, fc) == std::cmp::Ordering::Less;
                        let take_a = if *func == Builtin::Min {
                            less || fx::cmp(a, fa, c, fc).is_eq()
                        } else {
                            !less
                        };
                        if take_a {
                            fx::convert(a, fa, fr)
                        } else {
                            fx::convert(c, fc, fr)
                        }
                    }
                }
            }
        }
    }

    /// The fixed program this instance runs.
    pub fn program(&self) -> &'f FixedProgram {
        self.fp
    }
    /// Raw state words.
    pub fn states(&self) -> &[i32] {
        &self.states
    }
    /// Mode variant indices.
    pub fn modes(&self) -> &[u32] {
        &self.modes
    }
    /// Which values have saturated so far (overflow-detecting mode is always on).
    pub fn overflowed(&self) -> &[bool] {
        &self.overflowed
    }
    /// How many state writes were saturated to the declared range, per state.
    pub fn saturations(&self) -> &[u64] {
        &self.saturations
    }
    /// Every value's raw word as the last sample left it (truth values 0/1), indexed by
    /// [`Value`]: a value defined in an `if` body that did not run keeps an older sample's.
    pub fn values(&self) -> &[i32] {
        &self.vals
    }
}

impl RawOut {
    /// The same sample in SI units, for comparison with the f64 engines.
    pub fn to_si(&self, fp: &FixedProgram) -> crate::interp::SampleOut {
        crate::interp::SampleOut {
            forces: self
                .forces
                .iter()
                .zip(&fp.force_frac)
                .map(|(&x, &f)| fx::to_f64(x, f))
                .collect(),
            total: fx::to_f64(self.total, fp.total_frac),
            outputs: self
                .outputs
                .iter()
                .zip(&fp.output_frac)
                .map(|(&x, &f)| fx::to_f64(x, f))
                .collect(),
            events: self
                .events
                .iter()
                .map(|(e, a)| {
                    (
                        *e,
                        a.iter()
                            .zip(&fp.event_frac[e.index()])
                            .map(|(&x, &f)| fx::to_f64(x, f))
                            .collect(),
                    )
                })
                .collect(),
        }
    }
}

/// A product `x·y` (words with their fraction bits, in operand order) into `fr` fraction
/// bits in the form the plan chose for it (`kind`): [`fx::mul_shifted`] for a pre-shifted
/// `MULS`, [`fx::mul_32x16`] with the `cut` operand cut to 16 bits, [`fx::mul_high`], else
/// the exact [`fx::mul`]. The one dispatch for a product and a product by a reciprocal; the
/// JIT and the C output have one each, tested bit for bit against this one.
fn product(kind: Option<super::MulKind>, x: (i32, i32), y: (i32, i32), fr: i32) -> fx::Sat {
    let ((a, fa), (c, fc)) = (x, y);
    match kind {
        Some(super::MulKind::Muls(sa, sb)) => fx::mul_shifted(a, fa, sa, c, fc, sb, fr),
        Some(super::MulKind::High(k)) => fx::mul_high(a, fa, c, fc, k, fr),
        Some(super::MulKind::Mul32x16 { cut, b, k }) => {
            let ((a, fa), (c, fc)) = cut.kept_cut(x, y);
            fx::mul_32x16(a, fa, c, fc, b, k, fr)
        }
        _ => fx::mul(a, fa, c, fc, fr),
    }
}
