//! The fixed-point interpreter: the definition of the bits.
//!
//! It executes the same statement list as the f64 reference interpreter, on raw 32-bit
//! words in the formats of the [`FixedProgram`], with every operation computed by
//! [`tactus_runtime::fixed`]. The JIT, the Thumb code and the C code must reproduce its
//! output bit for bit. In overflow-detecting mode it records every value whose computation
//! saturated, so tests can check the range analysis's claim that nothing else ever does.
//!
//! An instance runs its program's body as resolved once by [`flat::Code`] (operand slots,
//! shifts and product forms decided per plan, the hot operations evaluated by the runtime's
//! resolved forms, [`fx::resolved`]); the values that have no such form are evaluated on the
//! IR by `FixedInstance::eval`, the runtime's general functions called as they stand.

mod flat;

use super::FixedProgram;
use crate::ir::*;
use flat::{Code, Ins};
use std::sync::Arc;
use tactus_runtime::differentiator::RawHistory;
use tactus_runtime::fixed as fx;
use tactus_runtime::fixed::resolved as rs;

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
    /// The body, resolved for this program ([`flat::Code`]); shared by clones.
    code: Arc<Code>,
    /// Buffer for [`FixedInstance::step`]'s converted readings.
    input: Vec<i32>,
    hist: Vec<RawHistory>,
    /// Every value's word, then the constant operands' ([`flat::Code::consts`]).
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
        Self::resolved(fp, params, false)
    }

    /// [`Self::with_params`] with the body resolved by [`flat::Code::new`] (`slow`: every
    /// value evaluated on the IR).
    fn resolved(fp: &'f FixedProgram, params: Vec<i32>, slow: bool) -> Self {
        let p = &fp.program;
        let code = Code::new(fp, slow);
        let mut vals = vec![0; p.values.len()];
        vals.extend_from_slice(&code.consts);
        for i in &code.preset {
            match *i {
                Ins::Word { dst, w } => vals[dst as usize] = w,
                Ins::Param { dst, slot } => {
                    vals[dst as usize] = params.get(slot as usize).copied().unwrap_or(0)
                }
                _ => {}
            }
        }
        FixedInstance {
            params,
            fp,
            code: Arc::new(code),
            states: fp.state_init.clone(),
            modes: p.modes.iter().map(|m| m.init).collect(),
            edges: vec![false; p.edges.len()],
            sensors: vec![0; p.sensors.len()],
            input: Vec::with_capacity(p.sensors.len()),
            hist: vec![RawHistory::default(); p.sensors.len()],
            vals,
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
        self.run();
        &self.out
    }

    /// Runs the resolved body once.
    fn run(&mut self) {
        let code = &*self.code;
        let ins = &code.ins[..];
        let mut pc = 0;
        while let Some(&i) = ins.get(pc) {
            pc += 1;
            let (dst, (x, o)) = match i {
                Ins::Word { dst, w } => (dst, (w, false)),
                Ins::Param { dst, slot } => (
                    dst,
                    (self.params.get(slot as usize).copied().unwrap_or(0), false),
                ),
                Ins::Sensor { dst, s, sh } => (dst, rs::convert(self.sensors[s as usize], sh)),
                Ins::State { dst, s, sh } => (dst, rs::convert(self.states[s as usize], sh)),
                Ins::Mode { dst, m } => (dst, (self.modes[m as usize] as i32, false)),
                Ins::Edge { dst, e } => (dst, (i32::from(self.edges[e as usize]), false)),
                Ins::Neg { dst, x, sh } => (dst, rs::neg(self.vals[x as usize], sh)),
                Ins::Abs { dst, x, sh } => (dst, rs::abs(self.vals[x as usize], sh)),
                Ins::Not { dst, x } => (dst, (i32::from(self.vals[x as usize] == 0), false)),
                Ins::And { dst, x, y } => (
                    dst,
                    (
                        i32::from(self.vals[x as usize] != 0 && self.vals[y as usize] != 0),
                        false,
                    ),
                ),
                Ins::Or { dst, x, y } => (
                    dst,
                    (
                        i32::from(self.vals[x as usize] != 0 || self.vals[y as usize] != 0),
                        false,
                    ),
                ),
                Ins::Add { dst, x, y, al } => {
                    (dst, al.add(self.vals[x as usize], self.vals[y as usize]))
                }
                Ins::Sub { dst, x, y, al } => {
                    (dst, al.sub(self.vals[x as usize], self.vals[y as usize]))
                }
                Ins::Mul { dst, x, y, p } => {
                    (dst, p.eval(self.vals[x as usize], self.vals[y as usize]))
                }
                Ins::Cmp {
                    dst,
                    x,
                    y,
                    al,
                    mask,
                } => {
                    let ord = al.cmp(self.vals[x as usize], self.vals[y as usize]);
                    (dst, (flat::holds(mask, ord), false))
                }
                Ins::CmpConst { dst, x, t, mask } => (
                    dst,
                    (flat::holds(mask, t.order(self.vals[x as usize])), false),
                ),
                Ins::Select {
                    dst,
                    c,
                    x,
                    y,
                    shx,
                    shy,
                } => {
                    let (w, sh) = if self.vals[c as usize] != 0 {
                        (x, shx)
                    } else {
                        (y, shy)
                    };
                    (dst, rs::convert(self.vals[w as usize], sh))
                }
                Ins::MinMax {
                    dst,
                    x,
                    y,
                    al,
                    shx,
                    shy,
                    min,
                } => {
                    let (a, c) = (self.vals[x as usize], self.vals[y as usize]);
                    let ord = al.cmp(a, c);
                    let take_a = if min {
                        ord != std::cmp::Ordering::Greater
                    } else {
                        ord != std::cmp::Ordering::Less
                    };
                    if take_a {
                        (dst, rs::convert(a, shx))
                    } else {
                        (dst, rs::convert(c, shy))
                    }
                }
                Ins::Slow { dst } => (dst, self.eval(Value(dst))),
                Ins::SetState { st, v, sh, lo, hi } => {
                    let (x, _) = rs::convert(self.vals[v as usize], sh);
                    let y = x.clamp(lo, hi);
                    if y != x {
                        self.saturations[st as usize] += 1;
                    }
                    self.states[st as usize] = y;
                    continue;
                }
                Ins::SetMode { m, i } => {
                    self.modes[m as usize] = i;
                    continue;
                }
                Ins::SetEdge { e, v } => {
                    self.edges[e as usize] = self.vals[v as usize] != 0;
                    continue;
                }
                Ins::Skip { c, to } => {
                    if self.vals[c as usize] == 0 {
                        pc = to as usize;
                    }
                    continue;
                }
                Ins::Emit { e, start, n } => {
                    let args = &code.args[start as usize..(start + n) as usize];
                    let a = args
                        .iter()
                        .map(|&(v, sh)| rs::convert(self.vals[v as usize], sh).0)
                        .collect();
                    self.out.events.push((EventId(e), a));
                    continue;
                }
                Ins::Force { f, v } => {
                    self.out.forces[f as usize] = self.vals[v as usize];
                    continue;
                }
                Ins::Output { o, v } => {
                    self.out.outputs[o as usize] = self.vals[v as usize];
                    continue;
                }
                Ins::Total { v } => {
                    self.out.total = self.vals[v as usize];
                    continue;
                }
            };
            self.vals[dst as usize] = x;
            if o {
                self.overflowed[dst as usize] = true;
            }
        }
    }

    /// The word of `v` by the definition on the IR: the runtime's function for its operation
    /// called with the operands' words and formats (the values [`flat::Code`] leaves
    /// [`Ins::Slow`]).
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
                    Builtin::Abs => fx::abs(a, fa, fr),
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
    /// [`Value`]: a value defined in an `if` body that did not run keeps an older sample's
    /// (before the first sample: 0, except the constants and params the body defines outside
    /// every `if`, which hold their words from the start).
    pub fn values(&self) -> &[i32] {
        &self.vals[..self.fp.program.values.len()]
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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::fixed::PlanConfig;
    use crate::lower::Config;
    use std::path::Path;
    use tactus_runtime::stimulus;

    /// Every instrument with the plan its error analysis proves (no simulated search: the
    /// test covers the interpreter, not the planner), and again with every product in each
    /// cheaper form the planner considered, so that every product form runs.
    fn plans() -> Vec<(String, FixedProgram)> {
        let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("../instruments");
        let mut names: Vec<_> = std::fs::read_dir(&dir)
            .unwrap()
            .filter_map(|e| e.ok()?.file_name().into_string().ok())
            .filter_map(|n| n.strip_suffix(".tactus").map(str::to_string))
            .collect();
        names.sort();
        assert!(names.len() >= 5, "instruments: {names:?}");
        let config = PlanConfig {
            simulate: false,
            ..PlanConfig::default()
        };
        let mut out = Vec::new();
        for name in names {
            let src = std::fs::read_to_string(dir.join(format!("{name}.tactus"))).unwrap();
            let p = crate::compile(&src, &Config::default()).unwrap().program;
            let fp = FixedProgram::with_config(&p, &config);
            for nth in 0..3 {
                let mut q = fp.clone();
                let mut changed = false;
                for (k, options) in q.mul_kind.iter_mut().zip(&fp.mul_options) {
                    if let Some(&o) = options.get(nth) {
                        *k = Some(o);
                        changed = true;
                    }
                }
                if changed {
                    out.push((format!("{name} (form {nth})"), q));
                }
            }
            out.push((name, fp));
        }
        // grand88's kind of program: the piano shared by two hammer masses, run-time params.
        let src = std::fs::read_to_string(dir.join("grand_piano.tactus")).unwrap();
        let keys: Vec<_> = ["11 g", "3.5 g"]
            .iter()
            .map(|m| {
                let c = Config {
                    overrides: vec![("M_h".into(), (*m).into())],
                    ..Config::default()
                };
                crate::compile(&src, &c).unwrap().program
            })
            .collect();
        let shared = crate::share::share(&keys).unwrap().program;
        assert!(shared.runtime_params().count() > 0);
        out.push((
            "shared piano".into(),
            FixedProgram::with_config(&shared, &config),
        ));
        out
    }

    /// The resolved body ([`flat::Code`]) against the definition on the IR (every value
    /// [`Ins::Slow`]): the same outputs, events, values, states, modes, overflow flags and
    /// saturation counts at every sample of two built-in stimuli (a strike and a half dip
    /// onto a stop; every k-th sample for a program of thousands of values) and of
    /// arbitrary sensor words (clamped to each sensor's range as every engine clamps them),
    /// on every instrument, a shared program and each product form.
    #[test]
    fn the_resolved_body_is_the_definition_on_the_ir() {
        let mut resolved = 0;
        for (name, fp) in plans() {
            let p = &fp.program;
            let code = Code::new(&fp, false);
            resolved += code
                .ins
                .iter()
                .filter(|i| !matches!(i, Ins::Slow { .. }))
                .count();
            let mut fast = FixedInstance::with_params(&fp, fp.nominal_param_block());
            let mut slow = FixedInstance::resolved(&fp, fp.nominal_param_block(), true);
            let mut inputs: Vec<Vec<i32>> = Vec::new();
            // A contact-point instrument of thousands of values (a bank, a string) runs
            // every k-th sample of each stroke (a faster stroke), about 1,000 a stimulus.
            let heavy = p.values.len() > 2_000;
            for stim in ["ff-dip", "half-dip"] {
                let s = stimulus::builtin(stim, p.sensors[0].range.1, p.sample_rate_hz).unwrap();
                let k = if heavy {
                    s.key.len().div_ceil(1000).max(1)
                } else {
                    1
                };
                inputs.extend(s.key.iter().step_by(k).map(|&k| {
                    (0..p.sensors.len())
                        .map(|i| {
                            FixedInstance::sensor_raw(&fp, i, Some(if i == 0 { k } else { 0.0 }))
                        })
                        .collect()
                }));
            }
            let mut r = 0x9e37_79b9_7f4a_7c15u64;
            for _ in 0..1000 {
                inputs.push(
                    (0..p.sensors.len())
                        .map(|_| {
                            r ^= r << 13;
                            r ^= r >> 7;
                            r ^= r << 17;
                            r as i32 >> (r >> 59)
                        })
                        .collect(),
                );
            }
            // The other product forms on the first 4000 samples (a strike): what they add is
            // the resolution of each form, whose arithmetic the runtime's tests cover.
            let limit = if name.contains("form") {
                4000
            } else {
                inputs.len()
            };
            for (n, x) in inputs.iter().take(limit).enumerate() {
                let a = fast.step_raw(x).clone();
                let b = slow.step_raw(x);
                assert_eq!(&a, b, "{name}: sample {n}");
                assert_eq!(fast.values(), slow.values(), "{name}: sample {n}");
                assert_eq!(fast.states(), slow.states(), "{name}: sample {n}");
                assert_eq!(fast.modes(), slow.modes(), "{name}: sample {n}");
                assert_eq!(fast.overflowed(), slow.overflowed(), "{name}: sample {n}");
                assert_eq!(fast.saturations(), slow.saturations(), "{name}: sample {n}");
            }
        }
        assert!(resolved > 1000, "only {resolved} resolved instructions");
    }
}
