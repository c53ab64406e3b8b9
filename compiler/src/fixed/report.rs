//! The precision report: error bounds of the fixed-point program against the f64 semantics.
//!
//! Bounds are absolute, in SI units, and *sound per operation*: each operation's bound is
//! the propagated bound of its operands (first-order interval error propagation, with the
//! operands' ranges from [`super::range`]) plus its own rounding — half an LSB of its format
//! when it rounds, a whole LSB for a truncating division, the algorithm's error for `exp`.
//! Both engines are assumed to see the same (quantised) sensor samples and to take the same
//! branches; a comparison that decides differently is not covered (it can only happen when
//! the compared values are within their error bounds of each other).
//!
//! States make the analysis a fixpoint: a state's bound is the largest bound of a value
//! written to it plus the rounding of the write. For states that are only set (a held
//! force, a mode-like position) the fixpoint converges. For integrated states (a hammer's
//! position and velocity) each sample adds its rounding, so no finite bound exists; they
//! are reported as *accumulating* with their one-sample (local) bound, and the forces that
//! depend on them as local bounds — their real error is measured against the f64 engine
//! in the tests.

use super::FixedProgram;
use crate::ir::*;

/// Error bounds of a fixed program.
#[derive(Clone, Debug)]
pub struct Precision {
    /// Bound of every value, SI.
    pub value: Vec<f64>,
    /// Bound of every state, SI (local one-sample bound for accumulating states).
    pub state: Vec<f64>,
    /// Whether each state's error accumulates over samples (no finite bound).
    pub accumulating: Vec<bool>,
    /// Bound of what one sample writes to each state (including the write's rounding),
    /// given the state bounds above, SI: for an accumulating state, the error one sample adds.
    pub write: Vec<f64>,
    /// Bound of each force term, N.
    pub force: Vec<f64>,
    /// Bound of the total force, N.
    pub total: f64,
    /// Whether the total depends on an accumulating state (the bound is then per sample).
    pub total_is_local: bool,
    /// Full-scale force of the DAC, N: the param `full_scale` if the instrument has one,
    /// else the largest magnitude of the total's range.
    pub full_scale_n: f64,
}

impl Precision {
    /// One LSB of a 16-bit bipolar DAC at full scale, N: `2·FS / 65536`.
    pub fn dac_lsb_n(&self) -> f64 {
        2.0 * self.full_scale_n / 65536.0
    }
}

fn half_lsb(f: i32) -> f64 {
    0.5 * pow2(-f)
}

/// `2^k`, exactly (as `2f64.powi(k)`, which is exact for powers of two, but without the
/// library call: the precision budget runs this analysis thousands of times).
pub(super) fn pow2(k: i32) -> f64 {
    if (-1022..=1023).contains(&k) {
        f64::from_bits(((1023 + k) as u64) << 52)
    } else {
        2f64.powi(k)
    }
}

/// Computes the error bounds of `fp`.
pub fn analyse(fp: &FixedProgram) -> Precision {
    let p = &fp.program;
    let init_err: Vec<f64> = p
        .states
        .iter()
        .enumerate()
        .map(|(i, s)| {
            (s.init - tactus_runtime::fixed::to_f64(fp.state_init[i], fp.state_frac[i])).abs()
        })
        .collect();
    let mut state = init_err.clone();
    let mut value = vec![0.0; p.values.len()];
    let mut accumulating = vec![false; p.states.len()];
    let mut converged = false;
    for _ in 0..64 {
        let (v, writes) = pass(fp, &state);
        value = v;
        let next: Vec<f64> = (0..p.states.len())
            .map(|i| writes[i].max(init_err[i]))
            .collect();
        // A bound that overflowed to infinity (or became NaN through 0·∞) has not converged.
        let grew: Vec<bool> = next
            .iter()
            .zip(&state)
            .map(|(n, o)| !n.is_finite() || *n > *o * (1.0 + 1e-9) + 1e-300)
            .collect();
        state = next;
        if !grew.iter().any(|g| *g) {
            converged = true;
            break;
        }
        accumulating = grew;
    }
    if converged {
        accumulating = vec![false; p.states.len()];
    } else {
        // Local bound: the state exact to its own rounding at the start of the sample.
        for (i, acc) in accumulating.iter().enumerate() {
            if *acc {
                state[i] = half_lsb(fp.state_frac[i]);
            }
        }
        value = pass(fp, &state).0;
    }
    let write = pass(fp, &state).1;
    let mut force = vec![0.0; p.forces.len()];
    let mut total = 0.0;
    collect(&p.body, &value, &mut force, &mut total);
    let full_scale_n = p
        .params
        .iter()
        .find(|x| x.name == "full_scale")
        .map(|x| x.value)
        .unwrap_or_else(|| total_range(fp));
    let total_is_local = accumulating.iter().any(|a| *a);
    Precision {
        value,
        state,
        accumulating,
        write,
        force,
        total,
        total_is_local,
        full_scale_n,
    }
}

fn total_range(fp: &FixedProgram) -> f64 {
    fn find(stmts: &[Stmt]) -> Option<Value> {
        stmts.iter().find_map(|s| match s {
            Stmt::Total(v) => Some(*v),
            Stmt::If(_, b) => find(b),
            _ => None,
        })
    }
    find(&fp.program.body).map_or(1.0, |v| fp.ranges.values[v.index()].mag())
}

fn collect(stmts: &[Stmt], value: &[f64], force: &mut [f64], total: &mut f64) {
    for s in stmts {
        match s {
            Stmt::Force(f, v) => force[f.index()] = value[v.index()],
            Stmt::Total(v) => *total = value[v.index()],
            Stmt::If(_, b) => collect(b, value, force, total),
            _ => {}
        }
    }
}

/// Each value's local error bound (SI): how far the fixed engines' word can lie from the
/// exact result of its operation on exact operands within their intervals, every state word
/// taken as exact (a state word is clamped into its range on every write, so a read lies in
/// its interval). So the value lies within its analysed interval widened by this bound —
/// what [`super::FixedProgram::widen_by_local_errors`] makes the interval say. Infinite
/// where the analysis has no bound (a division whose divisor may round to 0).
pub fn local_errors(fp: &FixedProgram) -> Vec<f64> {
    pass(fp, &vec![0.0; fp.program.states.len()]).0
}

/// One propagation pass: value bounds given state bounds, and the bound of each state's
/// writes (max over its `SetState`s, including the write's rounding).
fn pass(fp: &FixedProgram, state: &[f64]) -> (Vec<f64>, Vec<f64>) {
    let p = &fp.program;
    let mut e = vec![0.0; p.values.len()];
    let mut writes = vec![0.0f64; p.states.len()];
    fn walk(fp: &FixedProgram, stmts: &[Stmt], state: &[f64], e: &mut [f64], writes: &mut [f64]) {
        for s in stmts {
            match s {
                Stmt::Def(v) => e[v.index()] = op_error(fp, *v, state, e),
                Stmt::SetState(st, v) => {
                    let i = st.index();
                    let r = if fp.state_frac[i] < fp.frac[v.index()] {
                        half_lsb(fp.state_frac[i])
                    } else {
                        0.0
                    };
                    writes[i] = writes[i].max(e[v.index()] + r);
                }
                Stmt::If(_, b) => walk(fp, b, state, e, writes),
                _ => {}
            }
        }
    }
    walk(fp, &p.body, state, &mut e, &mut writes);
    (e, writes)
}

fn op_error(fp: &FixedProgram, v: Value, state: &[f64], e: &[f64]) -> f64 {
    let p = &fp.program;
    let fr = fp.frac[v.index()];
    let mag = |x: &Value| fp.ranges.values[x.index()].mag();
    let err = |x: &Value| e[x.index()];
    let round_from = |f: i32| if fr < f { half_lsb(fr) } else { 0.0 };
    match &p.values[v.index()].op {
        Op::Const(c) => (c - tactus_runtime::fixed::to_f64(fp.consts[v.index()], fr)).abs(),
        // A run-time param's word: rounded half up from any value in its interval.
        Op::Param(_) if fp.param_word_of(v).is_some() => half_lsb(fr),
        Op::Param(id) => (p.params[id.index()].value
            - tactus_runtime::fixed::to_f64(fp.consts[v.index()], fr))
        .abs(),
        Op::BoolConst(_)
        | Op::Variant(..)
        | Op::Mode(_)
        | Op::Edge(_)
        | Op::Not(_)
        | Op::Cmp(..)
        | Op::And(..)
        | Op::Or(..) => 0.0,
        Op::Sensor(s) => round_from(fp.sensor_frac[s.index()]),
        Op::Deriv(s, order) => {
            let (lo, hi) = p.sensors[s.index()].range;
            let r = p.sample_rate_hz / tactus_runtime::differentiator::WINDOW as f64;
            let (k, gain, span) = if *order == 1 {
                (fp.deriv_gain[0], r, hi - lo)
            } else {
                (fp.deriv_gain[1], r * r, 2.0 * (hi - lo))
            };
            span * (gain - tactus_runtime::fixed::to_f64(k.0, k.1)).abs() + half_lsb(fr)
        }
        Op::State(s) => state[s.index()] + round_from(fp.state_frac[s.index()]),
        Op::Neg(x) => err(x) + round_from(fp.frac[x.index()]),
        Op::Arith(o, x, y) => {
            let (fx, fy) = (fp.frac[x.index()], fp.frac[y.index()]);
            match o {
                ArithOp::Add | ArithOp::Sub => err(x) + err(y) + round_from(fx.max(fy)),
                ArithOp::Mul => {
                    let (ex, ey) = shift_errors(fp, v, fx, fy);
                    let (ex, ey) = (err(x) + ex, err(y) + ey);
                    mag(x) * ey + mag(y) * ex + ex * ey + high_error(fp, v, fx, fy) + half_lsb(fr)
                }
                ArithOp::Div => match fp.recip[v.index()] {
                    Some((r, f)) => {
                        let c = match p.values[y.index()].op {
                            Op::Const(c) => c,
                            Op::Param(id) => p.params[id.index()].value,
                            _ => f64::NAN,
                        };
                        let q = tactus_runtime::fixed::to_f64(r, f);
                        let (ex, eq) = shift_errors(fp, v, fx, f);
                        (err(x) + ex) * (q.abs() + eq)
                            + mag(x) * ((q - 1.0 / c).abs() + eq)
                            + high_error(fp, v, fx, f)
                            + half_lsb(fr)
                    }
                    None => {
                        let yr = fp.ranges.values[y.index()];
                        let ymin = if yr.lo > 0.0 {
                            yr.lo
                        } else if yr.hi < 0.0 {
                            -yr.hi
                        } else {
                            0.0
                        };
                        // The divisor's pre-shift (`fixed::div_shifted`) floors its word: an
                        // error below one LSB of the shifted word.
                        let b = fp.div_shift[v.index()];
                        let shift = if b > 0 { pow2(b as i32 - fy) } else { 0.0 };
                        if ymin <= shift {
                            f64::INFINITY
                        } else {
                            (err(x) + mag(&v) * (err(y) + shift)) / (ymin - shift)
                                + 2.0 * half_lsb(fr)
                        }
                    }
                },
            }
        }
        Op::Select(_, x, y) => {
            err(x).max(err(y)) + round_from(fp.frac[x.index()].max(fp.frac[y.index()]))
        }
        Op::Call(f, x, y) => {
            let fx = fp.frac[x.index()];
            match f {
                Builtin::Abs => err(x) + round_from(fx),
                Builtin::Min | Builtin::Max => {
                    let ey = y.map_or(0.0, |y| err(&y));
                    let fy = y.map_or(fx, |y| fp.frac[y.index()]);
                    err(x).max(ey) + round_from(fx.max(fy))
                }
                Builtin::Sqrt => {
                    let lo = fp.ranges.values[x.index()].lo;
                    let prop = if lo > 0.0 {
                        err(x) / (2.0 * lo.sqrt())
                    } else {
                        err(x).sqrt()
                    };
                    prop + half_lsb(fr)
                }
                Builtin::Exp => {
                    let hi = fp.ranges.values[x.index()].hi.exp();
                    // Propagated: e^(v+e) − e^v ≤ e^v·e·(1 + e) for e ≤ 1; the algorithm's
                    // own error (`fixed::EXP_REL_ERR`, relative) and the final rounding.
                    hi * err(x) * (1.0 + err(x))
                        + hi * tactus_runtime::fixed::EXP_REL_ERR
                        + half_lsb(fr)
                }
            }
        }
    }
}

/// The error of a high-word product ([`tactus_runtime::fixed::mul_high`]) before its
/// rounding: below `2 + 2^(32−k)` units of `2^(k − fx − fy)`; of a 32×16 product
/// ([`tactus_runtime::fixed::mul_32x16`]), its floor: below one unit of
/// `2^(b + k − fx − fy)` (its cut is an operand error, [`shift_errors`]); 0 for the other
/// forms.
fn high_error(fp: &FixedProgram, v: Value, fx: i32, fy: i32) -> f64 {
    match fp.mul_kind[v.index()] {
        Some(super::MulKind::High(k)) => {
            let k = k as i32;
            (2.0 + pow2(32 - k)) * pow2(k - fx - fy)
        }
        Some(super::MulKind::Mul32x16 { b, k, .. }) => pow2(b as i32 + k as i32 - fx - fy),
        _ => 0.0,
    }
}

/// How many low bits of `w`'s word are known to be zero on every sample: a constant's (or
/// compile-time param's) trailing zero bits; for a `select` whose arms are, recursively, such
/// values, the fewest trailing zeros of any arm's value on the select's own grid, when every
/// arm's value is exact there (the select converts the chosen arm's word to its format:
/// exact, so its word is that value's). 0 for every other value. Why: a pre-shift or a 32×16
/// cut drops these bits, and a floor of known zeros loses nothing — the piano's contact
/// stiffness and damping are selects of two constants (`k_jack`/`k_rep`, `b_jack`/`b_rep`)
/// whose words cut to 16 bits exactly, so their cut error is 0, not 1 LSB of the cut word
/// times the other operand's range (0.22 N of the contact force's bound before).
fn known_zero_bits(fp: &FixedProgram, w: Value) -> u8 {
    /// The values `v`'s word can hold, each exact on `v`'s grid, or `None` when not known.
    fn exact_values(fp: &FixedProgram, v: Value, depth: u32, out: &mut Vec<f64>) -> Option<()> {
        let f = fp.frac[v.index()];
        match fp.program.values[v.index()].op {
            Op::Select(_, a, b) if depth > 0 => {
                let start = out.len();
                exact_values(fp, a, depth - 1, out)?;
                exact_values(fp, b, depth - 1, out)?;
                // Each arm's value must be exact on the select's grid too.
                out[start..]
                    .iter()
                    .all(|&c| {
                        let word = c * pow2(f);
                        word.fract() == 0.0 && word.abs() < 2147483648.0
                    })
                    .then_some(())
            }
            _ => {
                let c = fp.program.const_value(v)?;
                (tactus_runtime::fixed::to_f64(fp.consts[v.index()], f) == c).then(|| out.push(c))
            }
        }
    }
    if matches!(fp.program.values[w.index()].op, Op::Select(..)) {
        if !matches!(fp.program.values[w.index()].ty, Ty::Real(_)) {
            return 0;
        }
        let mut values = Vec::new();
        if exact_values(fp, w, 8, &mut values).is_none() {
            return 0;
        }
        let f = fp.frac[w.index()];
        values
            .iter()
            .map(|&c| ((c * pow2(f)) as i64).trailing_zeros().min(32) as u8)
            .min()
            .unwrap_or(0)
    } else if fp.program.const_value(w).is_some() {
        fp.consts[w.index()].trailing_zeros() as u8
    } else {
        0
    }
}

/// The errors the pre-shifts of a `MULS` product, or the cut of a 32×16 product, add to its
/// operands (floor: < 1 LSB of the shifted operand).
fn shift_errors(fp: &FixedProgram, v: Value, fx: i32, fy: i32) -> (f64, f64) {
    let shifts = match fp.mul_kind[v.index()] {
        Some(super::MulKind::Muls(a, b)) => Some((a, b)),
        Some(super::MulKind::Mul32x16 { cut, b, .. }) => Some(match cut {
            super::Cut::First => (b, 0),
            super::Cut::Second => (0, b),
        }),
        _ => None,
    };
    match shifts {
        Some((a, b)) => {
            // A floor shift of a word loses less than one LSB of the shifted word, nothing
            // when the dropped bits are known zeros (`known_zero_bits`: a constant's trailing
            // zeros, or those of every constant a select chooses from).
            let (x, y) = match fp.program.values[v.index()].op {
                Op::Arith(_, x, y) => (x, y),
                _ => return (0.0, 0.0),
            };
            let free = |w: Value| known_zero_bits(fp, w);
            let fy_free = match fp.recip[v.index()] {
                Some((r, _)) => r.trailing_zeros() as u8,
                None => free(y),
            };
            let e = |s: u8, f: i32, free: u8| {
                if s <= free {
                    0.0
                } else {
                    pow2(s as i32 - f)
                }
            };
            (e(a, fx, free(x)), e(b, fy, fy_free))
        }
        _ => (0.0, 0.0),
    }
}

/// The value published by each force term.
pub fn force_values(p: &Program) -> Vec<Value> {
    let mut out = vec![Value(0); p.forces.len()];
    fn walk(stmts: &[Stmt], out: &mut [Value]) {
        for s in stmts {
            match s {
                Stmt::Force(f, v) => out[f.index()] = *v,
                Stmt::If(_, b) => walk(b, out),
                _ => {}
            }
        }
    }
    walk(&p.body, &mut out);
    out
}
