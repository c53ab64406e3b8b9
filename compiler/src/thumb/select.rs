//! Instruction selection: the fixed-point IR to [`M`] over virtual registers.
//!
//! Every IR operation computes the bits `tactus_runtime::fixed` defines (the same
//! reductions as the C backend's [`crate::cgen::prim`], written as ARMv6-M sequences). The
//! range analysis bounds every word: `bound(v) ≥ |raw word|` for each value, from its
//! interval and format, widened by a relative 1e-9 and one unit so that the f64 interval
//! arithmetic's rounding cannot make it unsound. Those bounds choose the sequence:
//!
//! * a sum whose terms provably fit 32 bits is `ADDS`/`SUBS` (plus the format shifts); other
//!   sums extend to 64 bits (`ADDS`/`ADCS`);
//! * saturation to `i32` is emitted only where the bound does not prove the word fits;
//! * a comparison of two words that cannot overflow is `SUBS` and a sign extraction
//!   (branch-free); a comparison with a constant uses the exact thresholds of
//!   [`crate::cgen::prim`];
//! * a multiplication planned for `MULS` is `ASRS` pre-shifts, one `MULS` and the rounding
//!   shift; a 64-bit product is four 16×16 `MULS` partial products combined with
//!   `ADDS`/`ADCS` (ARMv6-M has no `SMULL`);
//! * a right shift rounding half up by `m ≤ 31` is `ASRS #m-1; ADDS #1; ASRS #1`
//!   (`floor((floor(x/2^(m-1)) + 1)/2) = floor(x/2^m + 1/2)`).
//!
//! Booleans are words 0/1 where a value needs them (an edge, an output); a condition that
//! only an `if` tests is a chain of compare-and-branch instructions (short-circuit `and`/`or`,
//! `not` by the branch sense), and an `and`/`or` word with such operands is materialised by
//! branches. For the WCET analysis the selector also attaches flow facts
//! ([`crate::fixed::flow::exclusions`]):
//! pairs of top-level `if` bodies that cannot both run in one call.

use super::mir::*;
use super::ThumbError;
use crate::cgen::{prim, OutLayout, StateLayout};
use crate::fixed::flow::exclusions;
use crate::fixed::{FixedProgram, MulKind};
use crate::ir::*;
use std::cmp::Ordering;
use tactus_emulator::decode::{AluOp, MemOp};
use tactus_runtime::differentiator::WINDOW;

const LIM: u64 = 1 << 31;

/// A word and a bound on its magnitude.
#[derive(Clone, Copy, Debug)]
pub(crate) struct W {
    v: V,
    b: u64,
}

/// A selected function body and its number of virtual registers.
pub(crate) struct Selected {
    pub code: Vec<M>,
    pub nregs: u32,
    /// Pairs of top-level `if` statements (their [`M::Mark`]s) whose bodies never both run
    /// in one call ([`crate::fixed::flow::exclusions`]).
    pub exclusive: Vec<(u32, u32)>,
}

pub(crate) struct Sel<'a> {
    fp: &'a FixedProgram,
    p: &'a Program,
    st: &'a StateLayout,
    out: &'a OutLayout,
    code: Vec<M>,
    nv: u32,
    nl: u32,
    val: Vec<Option<W>>,
    used: Vec<bool>,
    sensors: Vec<W>,
    derivs: Vec<[Option<W>; 2]>,
    /// `d2()` of a sensor whose second difference does not fit 32 bits, as `(d1, e)` with
    /// `d2 = d1 − e`.
    d2_parts: Vec<Option<(W, W)>>,
    out_ptr: V,
    next_site: usize,
    /// Force/output/total slots written unconditionally exactly once: stored straight to
    /// `out[]`, not through `published[]`.
    direct: Vec<bool>,
    /// `state + region` in a register, for word accesses beyond the 124-byte reach of an
    /// immediate offset from r7 (`(region, register)`, region a multiple of 128): reused by
    /// the following accesses to the same region until the next label, where control may
    /// arrive from a path that did not define it.
    region_base: Option<(usize, V)>,
    /// Virtual registers holding a known word: defined once, by [`Sel::movi`] (a later
    /// definition removes the entry). A rounding of such a word is folded to its result
    /// ([`Sel::round`], [`Sel::floor_shr`]): a constant's conversion to another format costs
    /// nothing at run time.
    konst: std::collections::HashMap<V, i32>,
    /// The first construct found that this backend cannot compile.
    unsupported: Option<String>,
    /// Whether [`Sel::stmts`] is at the body's top level (for [`M::Mark`]s).
    top: bool,
    /// Conditions evaluated as branches where an `if` tests them, never as 0/1 words:
    /// `and`/`or`/`not`/comparisons whose only use is that `if` (or another such condition).
    fused: Vec<bool>,
}

/// The condition under which `a OP b` holds after `CMP a, b` (signed).
fn cond_of(o: CmpOp) -> Cond {
    match o {
        CmpOp::Eq => Cond::Eq,
        CmpOp::Ne => Cond::Ne,
        CmpOp::Lt => Cond::Lt,
        CmpOp::Le => Cond::Le,
        CmpOp::Gt => Cond::Gt,
        CmpOp::Ge => Cond::Ge,
    }
}

/// Two comparison operands brought to one grid ([`Sel::common_grid`]).
enum Grid {
    /// Both fit 32 bits on the finer grid.
    Words(W, W),
    /// They need 64 bits: each word with its left shift.
    Wide((W, i32), (W, i32)),
}

/// How a comparison came out when selected as flags.
enum Flags {
    /// `CMP` was emitted; the comparison holds when this condition does.
    Cond(Cond),
    /// The comparison is decided at compile time (a constant beyond the word's range).
    Known(bool),
}

/// The conditions [`Sel::branch`] evaluates as control flow (see `Sel::fused`).
fn fused_conditions(p: &Program, used: &[bool]) -> Vec<bool> {
    let n = p.values.len();
    let mut uses = vec![0u32; n];
    for (vd, _) in p.values.iter().zip(used).filter(|(_, u)| **u) {
        for x in crate::cgen::operands(&vd.op) {
            uses[x.index()] += 1;
        }
    }
    let mut conds = Vec::new();
    fn walk(stmts: &[Stmt], uses: &mut [u32], conds: &mut Vec<Value>) {
        for s in stmts {
            match s {
                Stmt::If(c, body) => {
                    uses[c.index()] += 1;
                    conds.push(*c);
                    walk(body, uses, conds);
                }
                Stmt::Def(_) | Stmt::SetMode(..) => {}
                Stmt::SetState(_, v)
                | Stmt::SetEdge(_, v)
                | Stmt::Force(_, v)
                | Stmt::Output(_, v)
                | Stmt::Total(v) => uses[v.index()] += 1,
                Stmt::Emit(_, args) => {
                    for v in args {
                        uses[v.index()] += 1;
                    }
                }
            }
        }
    }
    walk(&p.body, &mut uses, &mut conds);
    let mut fused = vec![false; n];
    let fusable = |v: Value, uses: &[u32]| {
        uses[v.index()] == 1
            && matches!(
                p.values[v.index()].op,
                Op::And(..) | Op::Or(..) | Op::Not(_) | Op::Cmp(..)
            )
    };
    // Roots: `if` conditions used once, and the operands (used once) of `and`/`or` values
    // that are kept as words — those are materialised by branches (see `Sel::def`).
    let mut stack: Vec<Value> = conds.into_iter().filter(|c| fusable(*c, &uses)).collect();
    for (i, vd) in p.values.iter().enumerate() {
        if let Op::And(x, y) | Op::Or(x, y) = vd.op {
            if used[i] && !stack.iter().any(|c| c.index() == i) {
                stack.extend([x, y].into_iter().filter(|x| fusable(*x, &uses)));
            }
        }
    }
    while let Some(v) = stack.pop() {
        fused[v.index()] = true;
        if let Op::And(x, y) | Op::Or(x, y) = p.values[v.index()].op {
            stack.extend([x, y].into_iter().filter(|x| fusable(*x, &uses)));
        } else if let Op::Not(x) = p.values[v.index()].op {
            if fusable(x, &uses) {
                stack.push(x);
            }
        }
    }
    fused
}

fn pow2(e: i32) -> u64 {
    if e >= 63 {
        u64::MAX
    } else {
        1u64 << e.max(0)
    }
}

fn shl_bound(b: u64, e: i32) -> u64 {
    if b == 0 {
        0
    } else if e >= 40 {
        u64::MAX
    } else {
        b.saturating_mul(pow2(e))
    }
}

impl<'a> Sel<'a> {
    pub(crate) fn new(
        fp: &'a FixedProgram,
        st: &'a StateLayout,
        out: &'a OutLayout,
        used: Vec<bool>,
    ) -> Self {
        let p = &fp.program;
        let np = p.forces.len() + 1 + p.outputs.len();
        let mut count = vec![(0usize, false); np];
        fn walk(stmts: &[Stmt], p: &Program, nested: bool, count: &mut [(usize, bool)]) {
            let nf = p.forces.len();
            for s in stmts {
                let slot = match s {
                    Stmt::Force(f, _) => Some(f.index()),
                    Stmt::Total(_) => Some(nf),
                    Stmt::Output(o, _) => Some(nf + 1 + o.index()),
                    Stmt::If(_, body) => {
                        walk(body, p, true, count);
                        None
                    }
                    _ => None,
                };
                if let Some(i) = slot {
                    count[i].0 += 1;
                    count[i].1 |= nested;
                }
            }
        }
        walk(&p.body, p, false, &mut count);
        let direct = count.iter().map(|&(n, nested)| n == 1 && !nested).collect();
        let fused = fused_conditions(p, &used);
        Sel {
            fp,
            p,
            st,
            out,
            code: Vec::new(),
            nv: 0,
            nl: 0,
            val: vec![None; p.values.len()],
            used,
            sensors: Vec::new(),
            derivs: vec![[None, None]; p.sensors.len()],
            d2_parts: vec![None; p.sensors.len()],
            out_ptr: V(0),
            next_site: 0,
            direct,
            region_base: None,
            konst: std::collections::HashMap::new(),
            unsupported: None,
            fused,
            top: false,
        }
    }

    fn nv(&mut self) -> V {
        self.nv += 1;
        V(self.nv - 1)
    }

    fn label(&mut self) -> Label {
        self.nl += 1;
        Label(self.nl - 1)
    }

    fn push(&mut self, m: M) {
        if matches!(m, M::Label(_)) {
            self.region_base = None;
        }
        if let Some(d) = m.def() {
            self.konst.remove(&d);
        }
        self.code.push(m);
    }

    /// For a word access at `off` bytes into the state struct beyond an immediate offset's
    /// reach: the base register of its 128-byte region and the offset within it (a delay
    /// line's shift then costs `LDR`/`STR` with immediate offsets, one address computation
    /// per 32 words).
    fn state_region(&mut self, off: usize) -> (V, u16) {
        let region = off & !127;
        if let Some((r, b)) = self.region_base {
            if r == region {
                return (b, (off - region) as u16);
            }
        }
        let o = self.movi(region as i32);
        let s = self.nv();
        self.push(M::Mov { d: s, s: STATE_V });
        let b = self.addsub(false, s, o);
        self.region_base = Some((region, b));
        (b, (off - region) as u16)
    }

    // ---- small builders ----

    fn movi(&mut self, imm: i32) -> V {
        let d = self.nv();
        self.push(M::Movi { d, imm });
        self.konst.insert(d, imm);
        d
    }

    /// A known word `c` as a `W` (its bound is its magnitude).
    fn known(&mut self, c: i32) -> W {
        W {
            v: self.movi(c),
            b: c.unsigned_abs() as u64,
        }
    }

    fn sh(&mut self, op: Shift, m: V, imm: u8) -> V {
        let d = self.nv();
        self.push(M::Sh { op, d, m, imm });
        d
    }

    fn alu2(&mut self, op: AluOp, a: V, m: V) -> V {
        let d = self.nv();
        self.push(M::Alu2 { op, d, a, m });
        d
    }

    fn addsub(&mut self, sub: bool, a: V, b: V) -> V {
        let d = self.nv();
        self.push(M::AddSub { sub, d, a, b });
        d
    }

    fn addi(&mut self, sub: bool, a: V, imm: u8) -> V {
        let d = self.nv();
        self.push(M::AddSubI { sub, d, a, imm });
        d
    }

    fn unary(&mut self, op: AluOp, m: V) -> V {
        let d = self.nv();
        self.push(M::Unary { op, d, m });
        d
    }

    fn load(&mut self, op: MemOp, base: Base, off: usize) -> V {
        let t = self.nv();
        if imm_offset(op, off) {
            self.push(M::Load {
                op,
                t,
                base,
                off: off as u16,
            });
        } else if base == Base::State && op == MemOp::Ldr && off.is_multiple_of(4) {
            let (b, o) = self.state_region(off);
            self.push(M::Load {
                op,
                t,
                base: Base::V(b),
                off: o,
            });
        } else {
            let idx = self.movi(off as i32);
            self.push(M::LoadR { op, t, base, idx });
        }
        t
    }

    fn store(&mut self, op: MemOp, t: V, base: Base, off: usize) {
        if imm_offset(op, off) {
            self.push(M::Store {
                op,
                t,
                base,
                off: off as u16,
            });
        } else {
            let addr = match base {
                // `STR Rt, [r7, Rm]` with the offset in a register (a delay line's shift
                // stores far into the state struct every sample).
                Base::State if op == MemOp::Str && off.is_multiple_of(4) => {
                    let (b, o) = self.state_region(off);
                    self.push(M::Store {
                        op,
                        t,
                        base: Base::V(b),
                        off: o,
                    });
                    return;
                }
                Base::State => {
                    let idx = self.movi(off as i32);
                    self.push(M::StoreR { op, t, idx });
                    return;
                }
                // Elsewhere the address is computed (such stores are rare).
                Base::V(b) => {
                    let o = self.movi(off as i32);
                    self.addsub(false, b, o)
                }
            };
            self.push(M::Store {
                op,
                t,
                base: Base::V(addr),
                off: 0,
            });
        }
    }

    // ---- fixed-point primitives on words ----

    /// `floor(x / 2^s)`.
    fn floor_shr(&mut self, x: W, s: i32) -> W {
        if s <= 0 {
            return x;
        }
        if let Some(&c) = self.konst.get(&x.v) {
            return self.known(c >> s.min(31));
        }
        let s = s.min(31) as u8;
        W {
            v: self.sh(Shift::Asr, x.v, s),
            b: (x.b >> s) + 1,
        }
    }

    /// `floor(x / 2^m + 1/2)` (round half up), `m ≥ 1`.
    fn rshr(&mut self, x: W, m: i32) -> W {
        if m >= 32 {
            // |x| < 2^31 ≤ 2^(m-1): rounds to 0.
            return W {
                v: self.movi(0),
                b: 0,
            };
        }
        let b = (x.b >> m) + 1;
        if m >= 2 || x.b < LIM - 1 {
            let t = if m >= 2 {
                self.sh(Shift::Asr, x.v, (m - 1) as u8)
            } else {
                x.v
            };
            let t = self.addi(false, t, 1);
            W {
                v: self.sh(Shift::Asr, t, 1),
                b,
            }
        } else {
            // m = 1 at the top of the range: the carry out of ASRS is the half bit.
            let t = self.sh(Shift::Asr, x.v, 1);
            let z = self.movi(0);
            W {
                v: self.alu2(AluOp::Adc, t, z),
                b,
            }
        }
    }

    /// `x · 2^e` saturated to i32, `e ≥ 1`.
    fn shl_sat(&mut self, x: W, e: i32) -> W {
        let b = shl_bound(x.b, e);
        if b < LIM {
            return W {
                v: self.sh(Shift::Lsl, x.v, e as u8),
                b,
            };
        }
        let done = self.label();
        let d;
        if e >= 32 {
            d = self.movi(0);
            self.push(M::CmpI { a: x.v, imm: 0 });
            self.push(M::Bc(Cond::Eq, done));
        } else {
            d = self.sh(Shift::Lsl, x.v, e as u8);
            let back = self.sh(Shift::Asr, d, e as u8);
            self.push(M::Cmp { a: back, b: x.v });
            self.push(M::Bc(Cond::Eq, done));
        }
        self.saturate_into(d, x.v);
        self.push(M::Label(done));
        W { v: d, b: LIM }
    }

    /// `d = sign(s) < 0 ? i32::MIN : i32::MAX` (a redefinition of `d`).
    fn saturate_into(&mut self, d: V, s: V) {
        let t = self.sh(Shift::Asr, s, 31);
        let t = self.unary(AluOp::Mvn, t);
        let min = self.movi(i32::MIN);
        self.push(M::Alu2 {
            op: AluOp::Eor,
            d,
            a: t,
            m: min,
        });
    }

    /// `x · 2^e` rounded half up and saturated (any `e`).
    fn round(&mut self, x: W, e: i32) -> W {
        if let Some(&c) = self.konst.get(&x.v) {
            if e != 0 {
                // The definition itself (`fixed::convert`: round half up, saturate).
                return self.known(tactus_runtime::fixed::convert(c, 0, e).0);
            }
        }
        match e.cmp(&0) {
            Ordering::Equal => x,
            Ordering::Greater => self.shl_sat(x, e),
            Ordering::Less => self.rshr(x, -e),
        }
    }

    fn convert(&mut self, x: W, from: i32, to: i32) -> W {
        self.round(x, to - from)
    }

    /// `-x` (exact: bounds are below 2^31, so `x ≠ i32::MIN`... unless unbounded).
    fn neg(&mut self, x: W) -> W {
        if x.b < LIM {
            W {
                v: self.unary(AluOp::Rsb, x.v),
                b: x.b,
            }
        } else {
            // -i32::MIN saturates.
            let d = self.unary(AluOp::Rsb, x.v);
            let done = self.label();
            self.push(M::Bc(Cond::Pl, done));
            self.push(M::Cmp { a: d, b: x.v });
            self.push(M::Bc(Cond::Ne, done));
            let m = self.movi(i32::MAX);
            self.push(M::Mov { d, s: m });
            self.push(M::Label(done));
            W { v: d, b: LIM - 1 }
        }
    }

    /// A 64-bit word pair `(lo, hi)` from a 32-bit word.
    fn ext(&mut self, x: V) -> (V, V) {
        (x, self.sh(Shift::Asr, x, 31))
    }

    /// `x · 2^k` as 64 bits, `0 ≤ k ≤ 31`.
    fn shl64(&mut self, x: V, k: i32) -> (V, V) {
        if k == 0 {
            return self.ext(x);
        }
        let lo = self.sh(Shift::Lsl, x, k as u8);
        let hi = self.sh(Shift::Asr, x, (32 - k) as u8);
        (lo, hi)
    }

    fn add64(&mut self, a: (V, V), b: (V, V), sub: bool) -> (V, V) {
        let lo = self.addsub(sub, a.0, b.0);
        let hi = self.alu2(if sub { AluOp::Sbc } else { AluOp::Adc }, a.1, b.1);
        (lo, hi)
    }

    /// Saturates a 64-bit pair to i32.
    fn sat64(&mut self, x: (V, V)) -> V {
        let d = self.nv();
        self.push(M::Mov { d, s: x.0 });
        let sign = self.sh(Shift::Asr, x.0, 31);
        self.push(M::Cmp { a: sign, b: x.1 });
        let done = self.label();
        self.push(M::Bc(Cond::Eq, done));
        self.saturate_into(d, x.1);
        self.push(M::Label(done));
        d
    }

    /// `round(x · 2^e)` of a 64-bit pair to a saturated i32; `bound` is the result's
    /// magnitude bound (saturation omitted when below 2^31).
    fn round64(&mut self, x: (V, V), e: i32, bound: u64) -> W {
        let fits = bound < LIM;
        if e >= 0 {
            let v = if e == 0 {
                if fits {
                    x.0
                } else {
                    self.sat64(x)
                }
            } else if fits {
                self.sh(Shift::Lsl, x.0, e.min(31) as u8)
            } else {
                // sat(x·2^e) = shl_sat(sat(x), e): a word outside i32 saturates either way.
                let s = self.sat64(x);
                self.shl_sat(W { v: s, b: LIM }, e).v
            };
            return W { v, b: bound };
        }
        let m = -e;
        if m >= 64 {
            return W {
                v: self.movi(0),
                b: 0,
            };
        }
        if fits {
            // Low word of floor(x / 2^m) plus the half bit (the carry out of the last shift).
            let v = if m < 32 {
                let t = self.sh(Shift::Lsl, x.1, (32 - m) as u8);
                let r = self.sh(Shift::Lsr, x.0, m as u8);
                let r = self.alu2(AluOp::Orr, r, t);
                let z = self.movi(0);
                self.alu2(AluOp::Adc, r, z)
            } else if m == 32 {
                let r = self.nv();
                self.push(M::Mov { d: r, s: x.1 });
                let _c = self.sh(Shift::Lsl, x.0, 1);
                let z = self.movi(0);
                self.alu2(AluOp::Adc, r, z)
            } else {
                let r = self.sh(Shift::Asr, x.1, (m - 32) as u8);
                let z = self.movi(0);
                self.alu2(AluOp::Adc, r, z)
            };
            return W { v, b: bound };
        }
        // Full 64-bit rounding shift, then saturation.
        let (lo, hi) = if m < 32 {
            let t = self.sh(Shift::Lsl, x.1, (32 - m) as u8);
            let hi = self.sh(Shift::Asr, x.1, m as u8);
            let lo = self.sh(Shift::Lsr, x.0, m as u8);
            let lo = self.alu2(AluOp::Orr, lo, t);
            let z = self.movi(0);
            let lo = self.alu2(AluOp::Adc, lo, z);
            let hi = self.alu2(AluOp::Adc, hi, z);
            (lo, hi)
        } else if m == 32 {
            let hi = self.sh(Shift::Asr, x.1, 31);
            let lo = self.nv();
            self.push(M::Mov { d: lo, s: x.1 });
            let _c = self.sh(Shift::Lsl, x.0, 1);
            let z = self.movi(0);
            let lo = self.alu2(AluOp::Adc, lo, z);
            let hi = self.alu2(AluOp::Adc, hi, z);
            (lo, hi)
        } else {
            let hi = self.sh(Shift::Asr, x.1, 31);
            let lo = self.sh(Shift::Asr, x.1, (m - 32) as u8);
            let z = self.movi(0);
            let lo = self.alu2(AluOp::Adc, lo, z);
            let hi = self.alu2(AluOp::Adc, hi, z);
            (lo, hi)
        };
        W {
            v: self.sat64((lo, hi)),
            b: bound.min(LIM),
        }
    }

    /// Signed 32×32 → 64-bit product from four 16×16 `MULS`.
    fn smull(&mut self, a: V, b: V) -> (V, V) {
        let al = self.nv();
        self.push(M::Uxth { d: al, m: a });
        let ah = self.sh(Shift::Asr, a, 16);
        let bl = self.nv();
        self.push(M::Uxth { d: bl, m: b });
        let bh = self.sh(Shift::Asr, b, 16);
        let lo = self.alu2(AluOp::Mul, al, bl);
        let hi = self.alu2(AluOp::Mul, ah, bh);
        let m1 = self.alu2(AluOp::Mul, ah, bl);
        let m2 = self.alu2(AluOp::Mul, al, bh);
        self.add_cross_terms((lo, hi), m1, m2)
    }

    /// `(lo, hi) + m1·2^16 + m2·2^16` as a 64-bit pair: the cross terms of a product from
    /// 16-bit halves (`lo`, `hi` the low·low and high·high products, `m1`, `m2` the mixed
    /// ones, each shifted into both words with its sign).
    fn add_cross_terms(&mut self, (lo, hi): (V, V), m1: V, m2: V) -> (V, V) {
        let t1 = self.sh(Shift::Lsl, m1, 16);
        let u1 = self.sh(Shift::Asr, m1, 16);
        let (lo, hi) = self.add64((lo, hi), (t1, u1), false);
        let t2 = self.sh(Shift::Lsl, m2, 16);
        let u2 = self.sh(Shift::Asr, m2, 16);
        self.add64((lo, hi), (t2, u2), false)
    }

    /// `x · y` with the given plan into a result of bound `rb`: `fx`, `fy` the operands'
    /// fraction bits, `fr` the result's.
    #[allow(clippy::too_many_arguments)]
    fn mul(&mut self, x: W, fx_: i32, y: Operand, fy: i32, fr: i32, kind: MulKind, rb: u64) -> W {
        match kind {
            MulKind::Muls(a, b) => {
                let xs = self.floor_shr(x, a as i32);
                let e = fr - (fx_ - a as i32) - (fy - b as i32);
                let prod = match y {
                    Operand::Const(c) => {
                        let c = ((c as i64) >> b.min(31)) as i32;
                        if c == 0 {
                            return W {
                                v: self.movi(0),
                                b: 0,
                            };
                        }
                        let k = c.unsigned_abs();
                        if k.is_power_of_two() {
                            // x · ±2^j: a shift (exact), negated when the constant is.
                            let j = k.trailing_zeros() as i32;
                            let base = if c < 0 { self.neg(xs) } else { xs };
                            return self.round(base, e + j);
                        }
                        let cv = self.movi(c);
                        W {
                            v: self.alu2(AluOp::Mul, xs.v, cv),
                            b: xs.b.saturating_mul(k as u64),
                        }
                    }
                    Operand::Word(y) => {
                        let ys = self.floor_shr(y, b as i32);
                        W {
                            v: self.alu2(AluOp::Mul, xs.v, ys.v),
                            b: xs.b.saturating_mul(ys.b),
                        }
                    }
                };
                self.round(prod, e)
            }
            MulKind::High(k) => {
                // fixed::mul_high: xh·yh·2^(32−k) + floor(xh·yl / 2^(k−16)) +
                // floor(xl·yh / 2^(k−16)), each partial product one MULS.
                let k = k.clamp(16, 32) as i32;
                let xh = self.sh(Shift::Asr, x.v, 16);
                // A constant's zero half contributes nothing: its partial products are 0
                // (`None`), and its register is never loaded.
                let (yh, yl, yb) = match y {
                    Operand::Const(c) => {
                        let half = |this: &mut Self, h: i32| (h != 0).then(|| this.movi(h));
                        (
                            half(self, c >> 16),
                            half(self, c & 0xffff),
                            c.unsigned_abs() as u64,
                        )
                    }
                    Operand::Word(w) => {
                        let yl = self.nv();
                        self.push(M::Uxth { d: yl, m: w.v });
                        (Some(self.sh(Shift::Asr, w.v, 16)), Some(yl), w.b)
                    }
                };
                let mut parts = Vec::with_capacity(3);
                if let Some(yh) = yh {
                    let mut hh = self.alu2(AluOp::Mul, xh, yh);
                    if k < 32 {
                        hh = self.sh(Shift::Lsl, hh, (32 - k) as u8);
                    }
                    parts.push(hh);
                }
                // x's low half only where a high half of y multiplies it.
                let xl = yh.map(|_| {
                    let xl = self.nv();
                    self.push(M::Uxth { d: xl, m: x.v });
                    xl
                });
                for (a, b) in [(Some(xh), yl), (xl, yh)] {
                    let (Some(a), Some(b)) = (a, b) else { continue };
                    let mut t = self.alu2(AluOp::Mul, a, b);
                    if k > 16 {
                        t = self.sh(Shift::Asr, t, (k - 16) as u8);
                    }
                    parts.push(t);
                }
                let mut p = match parts.first() {
                    Some(&t) => t,
                    None => self.movi(0),
                };
                for &t in parts.iter().skip(1) {
                    p = self.addsub(false, p, t);
                }
                // The planner's bound (`MulOperands::high`): the sum fits an i32.
                let (hx, hy) = ((x.b.min(LIM) >> 16) + 1, (yb.min(LIM) >> 16) + 1);
                let pb = ((hx * hy + hx + hy) << (32 - k)) + 2;
                if pb >= LIM {
                    self.unsupported("a high-word product whose partial sum may not fit 32 bits");
                }
                self.round(
                    W {
                        v: p,
                        b: pb.min(LIM),
                    },
                    fr - (fx_ + fy - k),
                )
            }
            MulKind::Wide => {
                let yv = match y {
                    Operand::Const(c) => self.movi(c),
                    Operand::Word(w) => w.v,
                };
                let p = self.smull(x.v, yv);
                self.round64(p, fr - fx_ - fy, rb)
            }
        }
    }

    /// `x ± y` into `fr` ([`fx::add`]); `rb` bounds the result.
    #[allow(clippy::too_many_arguments)]
    fn add(&mut self, x: W, fx_: i32, y: W, fy: i32, fr: i32, sub: bool, rb: u64) -> W {
        let (ex, ey) = (fr - fx_, fr - fy);
        // Both terms on the result grid or coarser: exact integer shifts.
        // One term on or above the grid: result = coarse·2^e1 ± round(fine·2^e2).
        let (coarse, e1, fine, e2, fine_is_y) = if ex >= ey {
            (x, ex, y, ey, true)
        } else {
            (y, ey, x, ex, false)
        };
        if e1 >= 0 && shl_bound(coarse.b, e1) < LIM {
            let cb = shl_bound(coarse.b, e1);
            // The fine term, negated first when it is the subtrahend.
            let fine_signed = if sub && fine_is_y {
                self.neg(fine)
            } else {
                fine
            };
            let fb = shl_bound(fine.b, e2.max(0)) + 1;
            let fine_fits = e2 < 0 || shl_bound(fine.b, e2) < LIM;
            if fine_fits && cb + (fb >> (-e2).max(0)) + 1 < LIM {
                let f = if e2 >= 0 {
                    self.round(fine_signed, e2)
                } else {
                    self.rshr(fine_signed, -e2)
                };
                let c = self.round(coarse, e1);
                let (a, b, s) = if fine_is_y {
                    (c, f, false)
                } else {
                    (f, c, sub)
                };
                // fine_is_y: c + f (f already negated for a subtraction);
                // else the coarse term is y: f - c or f + c.
                let v = self.addsub(s, a.v, b.v);
                return W { v, b: rb.min(LIM) };
            }
        }
        // Both finer than the result (or no 32-bit proof): the definition's reduction.
        let g = e2.max(e1.min(-1));
        let sy = (g - e2).min(63);
        let dx = e1 - g;
        if dx > 31 {
            return self.add64_path(x, fx_, y, fy, fr, sub, rb);
        }
        let fine_signed = if sub && fine_is_y {
            self.neg(fine)
        } else {
            fine
        };
        let f = self.floor_shr(fine_signed, sy);
        let cb = shl_bound(coarse.b, dx);
        if cb + f.b < LIM {
            let c = if dx > 0 {
                W {
                    v: self.sh(Shift::Lsl, coarse.v, dx as u8),
                    b: cb,
                }
            } else {
                coarse
            };
            let s = if fine_is_y {
                self.addsub(false, c.v, f.v)
            } else {
                self.addsub(sub, f.v, c.v)
            };
            let r = self.round(W { v: s, b: cb + f.b }, g);
            return W {
                v: r.v,
                b: rb.min(r.b),
            };
        }
        self.add64_path(x, fx_, y, fy, fr, sub, rb)
    }

    /// The sum in 64 bits (both terms extended and shifted to the finer grid, which is at
    /// most 31 bits below the coarser), then rounded.
    #[allow(clippy::too_many_arguments)]
    fn add64_path(&mut self, x: W, fx_: i32, y: W, fy: i32, fr: i32, sub: bool, rb: u64) -> W {
        let f = fx_.max(fy);
        let (sx, sy) = (f - fx_, f - fy);
        if sx > 31 || sy > 31 {
            // Formats more than 31 bits apart: not reachable from the shipped instruments.
            self.unsupported("a sum of operands whose formats differ by more than 31 bits");
            return W {
                v: self.movi(0),
                b: 0,
            };
        }
        let a = self.shl64(x.v, sx);
        let b = self.shl64(y.v, sy);
        let s = self.add64(a, b, sub);
        self.round64(s, fr - f, rb)
    }

    /// Records the first construct this backend cannot compile ([`Sel::run`] reports it).
    fn unsupported(&mut self, what: &str) {
        self.unsupported.get_or_insert_with(|| what.to_string());
    }
}

/// The second operand of a multiplication.
#[derive(Clone, Copy, Debug)]
pub(crate) enum Operand {
    /// A word in a register.
    Word(W),
    /// A raw constant word.
    Const(i32),
}

/// Whether byte offset `off` fits the immediate form of a load/store (imm5, scaled by the
/// access size).
fn imm_offset(op: MemOp, off: usize) -> bool {
    let size = op.size() as usize;
    off <= 31 * size && off.is_multiple_of(size)
}

/// Cycles between the SIO divider's operand write and a valid result read
/// (`emulator/src/timing.rs`, the one table).
fn timing_divider_latency() -> u32 {
    tactus_emulator::timing::DIVIDER_LATENCY
}

/// The pinned state pointer as a virtual register for address arithmetic (allocated to r7).
pub(crate) const STATE_V: V = V(u32::MAX);

impl<'a> Sel<'a> {
    fn bound_of(&self, v: Value) -> u64 {
        let fp = self.fp;
        match self.p.values[v.index()].ty {
            Ty::Bool => 1,
            Ty::Mode(m) => self.p.modes[m.index()].variants.len() as u64,
            Ty::Real(_) => {
                let mag = fp.ranges.values[v.index()].mag();
                let f = fp.frac[v.index()];
                let b = (mag * 2f64.powi(f) * (1.0 + 1e-9)).ceil() + 1.0;
                if b.is_finite() && b < LIM as f64 {
                    b as u64
                } else {
                    LIM
                }
            }
        }
    }

    /// The word of an operand value (constants are rematerialised at each use).
    fn word(&mut self, v: Value) -> W {
        if let Some(k) = self.fp.param_word_of(v) {
            // A run-time param: the key's word in the param block inside its state (an
            // `LDR` from r7, as cheap as the literal-pool `LDR` of a constant).
            let (lo, hi) = self.fp.param_words[k].raw_range;
            let t = self.load(MemOp::Ldr, Base::State, self.st.params + 4 * k);
            return W {
                v: t,
                b: (lo as i64).unsigned_abs().max((hi as i64).unsigned_abs()),
            };
        }
        match self.p.values[v.index()].op {
            Op::Const(_) | Op::Param(_) => {
                let c = self.fp.consts[v.index()];
                W {
                    v: self.movi(c),
                    b: c.unsigned_abs() as u64,
                }
            }
            Op::BoolConst(t) => W {
                v: self.movi(t as i32),
                b: 1,
            },
            Op::Variant(_, i) => W {
                v: self.movi(i as i32),
                b: i as u64,
            },
            _ => self.val[v.index()].expect("IR value used before its definition"),
        }
    }

    /// Whether `v` is the constant truth value `false` or a mode's first variant (word 0).
    fn is_zero_word(&self, v: Value) -> bool {
        matches!(
            self.p.values[v.index()].op,
            Op::BoolConst(false) | Op::Variant(_, 0)
        )
    }

    fn is_const(&self, v: Value) -> bool {
        self.p.const_value(v).is_some()
    }

    /// Selects the whole update body.
    pub(crate) fn run(mut self) -> Result<Selected, ThumbError> {
        let (p, fp, st) = (self.p, self.fp, self.st);
        // Arguments: r0 = state (copied to r7 by the prologue), r1 = sensors, r2 = out.
        let sensors_ptr = ARG1;
        self.out_ptr = ARG2;
        self.nv = FIRST_FREE;
        // 1. Sensors: load, clamp, push the histories.
        for (i, _sd) in p.sensors.iter().enumerate() {
            let raw = self.load(MemOp::Ldr, Base::V(sensors_ptr), 4 * i);
            let (lo, hi) = fp.sensor_raw_range[i];
            self.clamp(raw, lo, hi);
            let b = (lo as i64).unsigned_abs().max((hi as i64).unsigned_abs());
            self.sensors.push(W { v: raw, b });
        }
        let mut slot = 0;
        for (i, sd) in p.sensors.iter().enumerate() {
            if !sd.differentiated {
                continue;
            }
            self.history(i, slot)?;
            slot += 1;
        }
        // Clear the emit slots of out[].
        if !self.out.emits.is_empty() {
            let z = self.movi(0);
            for site in self.out.emits.clone() {
                let n = 1 + p.events[site.event.index()].args.len();
                for k in 0..n {
                    self.store(MemOp::Str, z, Base::V(self.out_ptr), 4 * (site.offset + k));
                }
            }
        }
        let body = p.body.clone();
        self.top = true;
        self.stmts(&body)?;
        // Published slots not stored directly: copy published[] to out[].
        let np = p.forces.len() + 1 + p.outputs.len();
        for i in 0..np {
            if !self.direct[i] {
                let w = self.load(MemOp::Ldr, Base::State, st.published + 4 * i);
                self.store(MemOp::Str, w, Base::V(self.out_ptr), 4 * i);
            }
        }
        if let Some(what) = self.unsupported {
            return Err(ThumbError::Unsupported(what));
        }
        // Constants nothing reads (the zero side of a `select` folded to `ANDS`/`BICS`):
        // `MOVS #imm` and literal loads have no effect the code relies on (N and Z of a
        // `MOVS` are never tested: every branch follows its own compare).
        let mut used = vec![false; self.nv as usize];
        for m in &self.code {
            for u in m.uses() {
                // (Fixed registers are numbered from the top: never a `Movi`'s.)
                if let Some(x) = used.get_mut(u.0 as usize) {
                    *x = true;
                }
            }
        }
        self.code
            .retain(|m| !matches!(m, M::Movi { d, .. } if used.get(d.0 as usize) == Some(&false)));
        Ok(Selected {
            code: self.code,
            nregs: self.nv,
            exclusive: exclusions(fp),
        })
    }

    /// Clamps `x` (redefined in place) to `[lo, hi]`.
    fn clamp(&mut self, x: V, lo: i32, hi: i32) {
        if self.konst.get(&x).is_some_and(|c| (lo..=hi).contains(c)) {
            return;
        }
        for (bound, cond) in [(lo, Cond::Ge), (hi, Cond::Le)] {
            if (cond == Cond::Ge && bound == i32::MIN) || (cond == Cond::Le && bound == i32::MAX) {
                continue;
            }
            let ok = self.label();
            let k = if (0..=255).contains(&bound) {
                self.push(M::CmpI {
                    a: x,
                    imm: bound as u8,
                });
                None
            } else {
                let k = self.movi(bound);
                self.push(M::Cmp { a: x, b: k });
                Some(k)
            };
            self.push(M::Bc(cond, ok));
            match k {
                Some(k) => self.push(M::Mov { d: x, s: k }),
                None => self.push(M::Movi { d: x, imm: bound }),
            }
            self.push(M::Label(ok));
        }
    }

    /// The differentiator ring of sensor `i` (history slot `h`): prime, advance, store,
    /// and the raw differences `d()`/`d2()` need.
    fn history(&mut self, i: usize, h: usize) -> Result<(), ThumbError> {
        let (p, st) = (self.p, self.st);
        let hlen = 2 * WINDOW + 1;
        let s = self.sensors[i];
        let base = st.hist + 4 * hlen * h;
        // Prime on the first sample: fill the ring with this reading.
        let primed = self.load(MemOp::Ldrb, Base::State, st.hist_primed + h);
        let skip = self.label();
        self.push(M::CmpI { a: primed, imm: 0 });
        self.push(M::Bc(Cond::Ne, skip));
        for k in 0..hlen {
            self.store(MemOp::Str, s.v, Base::State, base + 4 * k);
        }
        let one = self.movi(1);
        self.store(MemOp::Strb, one, Base::State, st.hist_primed + h);
        self.push(M::Label(skip));
        // pos = (pos + 1) mod 17
        let pos = self.load(MemOp::Ldrb, Base::State, st.hist_pos + h);
        let pos1 = self.addi(false, pos, 1);
        let wrap = self.label();
        self.push(M::CmpI {
            a: pos1,
            imm: hlen as u8,
        });
        self.push(M::Bc(Cond::Ne, wrap));
        self.push(M::Movi { d: pos1, imm: 0 });
        self.push(M::Label(wrap));
        self.store(MemOp::Strb, pos1, Base::State, st.hist_pos + h);
        // Address of the ring: state + base.
        let ring = {
            let sv = self.nv();
            self.push(M::Mov { d: sv, s: STATE_V });
            if base <= 255 {
                self.addi(false, sv, base as u8)
            } else {
                let o = self.movi(base as i32);
                self.addsub(false, sv, o)
            }
        };
        let off0 = self.sh(Shift::Lsl, pos1, 2);
        let addr = self.addsub(false, ring, off0);
        self.push(M::Store {
            op: MemOp::Str,
            t: s.v,
            base: Base::V(addr),
            off: 0,
        });
        let span = {
            let (lo, hi) = self.fp.sensor_raw_range[i];
            (hi as i64 - lo as i64).unsigned_abs()
        };
        let ago = |this: &mut Self, back: usize| -> V {
            // index (pos + hlen - back) mod hlen
            let t = this.addi(false, pos1, (hlen - back) as u8);
            let ok = this.label();
            this.push(M::CmpI {
                a: t,
                imm: hlen as u8,
            });
            this.push(M::Bc(Cond::Lt, ok));
            this.push(M::AddSubI {
                sub: true,
                d: t,
                a: t,
                imm: hlen as u8,
            });
            this.push(M::Label(ok));
            let off = this.sh(Shift::Lsl, t, 2);
            let w = this.nv();
            this.push(M::LoadR {
                op: MemOp::Ldr,
                t: w,
                base: Base::V(ring),
                idx: off,
            });
            w
        };
        let used1 = self.deriv_used(i, 1);
        let used2 = self.deriv_used(i, 2);
        if used1 || used2 {
            if span >= LIM {
                return Err(ThumbError::Unsupported(format!(
                    "d() of sensor `{}`: its raw range spans more than 2^30, so its differences do not fit 32 bits",
                    p.sensors[i].name
                )));
            }
            let n_ago = ago(self, WINDOW);
            let d1 = self.addsub(true, s.v, n_ago);
            if used1 {
                self.derivs[i][0] = Some(W { v: d1, b: span });
            }
            if used2 {
                let n2_ago = ago(self, 2 * WINDOW);
                // x0 - 2 x_N + x_2N = d1 - (x_N - x_2N)
                let e = self.addsub(true, n_ago, n2_ago);
                if 2 * span < LIM {
                    let d2 = self.addsub(true, d1, e);
                    self.derivs[i][1] = Some(W { v: d2, b: 2 * span });
                } else {
                    // d2 needs 33 bits: keep its two differences (k·d2 = k·d1 − k·e).
                    self.d2_parts[i] = Some((W { v: d1, b: span }, W { v: e, b: span }));
                }
            }
        }
        Ok(())
    }

    fn deriv_used(&self, s: usize, order: u8) -> bool {
        self.p.values.iter().enumerate().any(|(i, vd)| {
            self.used[i] && matches!(vd.op, Op::Deriv(x, o) if x.index() == s && o == order)
        })
    }

    fn stmts(&mut self, stmts: &[Stmt]) -> Result<(), ThumbError> {
        let (p, fp, st) = (self.p, self.fp, self.st);
        let top = std::mem::replace(&mut self.top, false);
        for (k, s) in stmts.iter().enumerate() {
            match s {
                Stmt::Def(v) => {
                    let word_only = matches!(
                        p.values[v.index()].op,
                        Op::Const(_) | Op::Param(_) | Op::BoolConst(_) | Op::Variant(..)
                    );
                    if self.used[v.index()] && !word_only && !self.fused[v.index()] {
                        let w = self.def(*v)?;
                        self.val[v.index()] = Some(w);
                    }
                }
                Stmt::SetState(sid, v) => {
                    let i = sid.index();
                    let x = self.word(*v);
                    let t = self.convert(x, fp.frac[v.index()], fp.state_frac[i]);
                    let (lo, hi) = fp.state_raw_range[i];
                    // The clamp is omitted where the value's interval proves it inside.
                    let iv = fp.ranges.values[v.index()];
                    let scale = 2f64.powi(fp.state_frac[i]);
                    let margin = 2.0 + 1e-9 * iv.mag() * scale;
                    // A state copied into a state of the same format and a range at least
                    // as wide (a delay line's shift) is inside too: every state word is
                    // within its own raw range (initialised in it, clamped on each write).
                    let copy = match p.values[v.index()].op {
                        Op::State(src) => {
                            let (slo, shi) = fp.state_raw_range[src.index()];
                            fp.state_frac[src.index()] == fp.state_frac[i]
                                && fp.frac[v.index()] == fp.state_frac[i]
                                && slo >= lo
                                && shi <= hi
                        }
                        _ => false,
                    };
                    let inside = copy
                        || (iv.lo * scale - margin >= lo as f64
                            && iv.hi * scale + margin <= hi as f64);
                    let t = if inside {
                        t.v
                    } else {
                        let c = self.nv();
                        self.push(M::Mov { d: c, s: t.v });
                        self.clamp(c, lo, hi);
                        c
                    };
                    self.store(MemOp::Str, t, Base::State, st.states + 4 * i);
                }
                Stmt::SetMode(m, i) => {
                    let k = self.movi(*i as i32);
                    self.store(MemOp::Strb, k, Base::State, st.modes + m.index());
                }
                Stmt::SetEdge(e, v) => {
                    let w = self.word(*v);
                    self.store(MemOp::Strb, w.v, Base::State, st.edges + e.index());
                }
                // `while true { … }`: the body, without a test (no flow fact can name it:
                // a body that always runs excludes nothing).
                Stmt::If(c, body) if p.values[c.index()].op == Op::BoolConst(true) => {
                    self.stmts(body)?;
                }
                Stmt::If(c, body) => {
                    let skip = self.label();
                    self.branch(*c, false, skip)?;
                    if top {
                        self.push(M::Mark(k as u32));
                    }
                    self.push(M::Note(format!("if {}", describe(p, *c))));
                    self.stmts(body)?;
                    self.push(M::Label(skip));
                }
                Stmt::Emit(e, args) => {
                    let site = self.out.emits[self.next_site];
                    self.next_site += 1;
                    self.push(M::Note(format!("emit {}", p.events[e.index()].name)));
                    let one = self.movi(1);
                    self.store(MemOp::Str, one, Base::V(self.out_ptr), 4 * site.offset);
                    for (j, (a, f)) in args.iter().zip(&fp.event_frac[e.index()]).enumerate() {
                        let x = self.word(*a);
                        let w = self.convert(x, fp.frac[a.index()], *f);
                        self.store(
                            MemOp::Str,
                            w.v,
                            Base::V(self.out_ptr),
                            4 * (site.offset + 1 + j),
                        );
                    }
                }
                Stmt::Force(f, v) => self.publish(f.index(), *v),
                Stmt::Total(v) => self.publish(p.forces.len(), *v),
                Stmt::Output(o, v) => self.publish(p.forces.len() + 1 + o.index(), *v),
            }
        }
        Ok(())
    }

    /// Branches to `target` when the truth value `v` equals `when`; falls through otherwise.
    /// A fused condition becomes compare-and-branch chains (short-circuit `and`/`or`, `not`
    /// by swapping the sense); any other value is tested as its 0/1 word.
    fn branch(&mut self, v: Value, when: bool, target: Label) -> Result<(), ThumbError> {
        if !self.fused[v.index()] {
            let w = self.word(v);
            self.push(M::CmpI { a: w.v, imm: 0 });
            self.push(M::Bc(if when { Cond::Ne } else { Cond::Eq }, target));
            return Ok(());
        }
        self.branch_op(v, when, target)
    }

    /// [`Sel::branch`] on the operation of `v` itself (an `and`, `or`, `not` or comparison),
    /// whether or not `v` is fused; its operands follow their own fusion.
    fn branch_op(&mut self, v: Value, when: bool, target: Label) -> Result<(), ThumbError> {
        match self.p.values[v.index()].op {
            Op::Not(x) => self.branch(x, !when, target),
            Op::And(x, y) | Op::Or(x, y) => {
                // `and` falls to `target` on the first false operand when testing for false;
                // `or` dually. The other sense needs a local label for the early exit.
                let is_and = matches!(self.p.values[v.index()].op, Op::And(..));
                if when != is_and {
                    self.branch(x, when, target)?;
                    self.branch(y, when, target)
                } else {
                    let out = self.label();
                    self.branch(x, !when, out)?;
                    self.branch(y, when, target)?;
                    self.push(M::Label(out));
                    Ok(())
                }
            }
            Op::Cmp(o, x, y) => match self.cmp_flags(o, x, y) {
                Some(Flags::Cond(c)) => {
                    self.push(M::Bc(if when { c } else { c.invert() }, target));
                    Ok(())
                }
                Some(Flags::Known(holds)) => {
                    if holds == when {
                        self.push(M::B(target));
                    }
                    Ok(())
                }
                None => {
                    let w = self.def(v)?;
                    self.push(M::CmpI { a: w.v, imm: 0 });
                    self.push(M::Bc(if when { Cond::Ne } else { Cond::Eq }, target));
                    Ok(())
                }
            },
            _ => unreachable!("only and/or/not/comparisons are branched on"),
        }
    }

    /// `x OP y` as a `CMP` and the condition under which it holds, when one 32-bit `CMP`
    /// decides it exactly (signed conditions use N, Z and V, so no overflow case is left
    /// out); `None` when it needs the 64-bit or two-threshold forms.
    fn cmp_flags(&mut self, o: CmpOp, x: Value, y: Value) -> Option<Flags> {
        let fp = self.fp;
        let real = |v: Value| matches!(self.p.values[v.index()].ty, Ty::Real(_));
        // Compare with a known word: `CMP #imm` when it fits 8 bits.
        let with_word = |this: &mut Self, a: V, t: i32| {
            if (0..=255).contains(&t) {
                this.push(M::CmpI { a, imm: t as u8 });
            } else {
                let k = this.movi(t);
                this.push(M::Cmp { a, b: k });
            }
        };
        if !real(x) || !real(y) {
            // Truth values and modes: small non-negative words.
            let small = |v: Value| match self.p.values[v.index()].op {
                Op::Variant(_, i) => Some(i as i32),
                Op::BoolConst(t) => Some(t as i32),
                _ => None,
            };
            let (a, o, k) = match (small(x), small(y)) {
                (_, Some(k)) => (x, o, k),
                (Some(k), None) => (y, o.mirrored(), k),
                (None, None) => {
                    let (a, b) = (self.word(x), self.word(y));
                    self.push(M::Cmp { a: a.v, b: b.v });
                    return Some(Flags::Cond(cond_of(o)));
                }
            };
            let w = self.word(a);
            with_word(self, w.v, k);
            return Some(Flags::Cond(cond_of(o)));
        }
        let konst = |v: Value| fp.exact_const(v);
        if let (None, Some(c)) | (Some(c), None) = (konst(x), konst(y)) {
            let const_left = konst(x).is_some();
            let (v, o) = if const_left {
                (y, o.mirrored())
            } else {
                (x, o)
            };
            let (ge, gt) = prim::thresholds(fp.frac[v.index()], c);
            let (lo, hi) = (i32::MIN as i64, i32::MAX as i64);
            // x >= t, x < t as flags; a threshold beyond the word range decides alone.
            let at_least = |this: &mut Self, t: i64, holds_if_ge: bool| -> Flags {
                if t <= lo || t > hi {
                    return Flags::Known((t <= lo) == holds_if_ge);
                }
                let w = this.word(v);
                with_word(this, w.v, t as i32);
                Flags::Cond(if holds_if_ge { Cond::Ge } else { Cond::Lt })
            };
            return match o {
                CmpOp::Ge => Some(at_least(self, ge, true)),
                CmpOp::Lt => Some(at_least(self, ge, false)),
                CmpOp::Gt => Some(at_least(self, gt, true)),
                CmpOp::Le => Some(at_least(self, gt, false)),
                CmpOp::Eq | CmpOp::Ne if ge == gt => Some(Flags::Known(o == CmpOp::Ne)),
                CmpOp::Eq | CmpOp::Ne if gt == ge + 1 && ge > lo && ge <= hi => {
                    let w = self.word(v);
                    with_word(self, w.v, ge as i32);
                    Some(Flags::Cond(cond_of(o)))
                }
                _ => None,
            };
        }
        let (fa, fb) = (fp.frac[x.index()], fp.frac[y.index()]);
        let (a, b) = (self.word(x), self.word(y));
        if a.v == b.v && fa == fb {
            return Some(Flags::Known(matches!(o, CmpOp::Eq | CmpOp::Le | CmpOp::Ge)));
        }
        match self.common_grid(a, fa, b, fb) {
            Grid::Words(a, b) => {
                self.push(M::Cmp { a: a.v, b: b.v });
                Some(Flags::Cond(cond_of(o)))
            }
            // Equality of 64-bit words needs the word form (Z is not the 64-bit Z).
            Grid::Wide(..) if matches!(o, CmpOp::Eq | CmpOp::Ne) => None,
            Grid::Wide(a, b) => Some(Flags::Cond(self.cmp64_ordered(o, a, b))),
        }
    }

    fn publish(&mut self, slot: usize, v: Value) {
        let w = self.word(v);
        if self.direct[slot] {
            self.store(MemOp::Str, w.v, Base::V(self.out_ptr), 4 * slot);
        } else {
            self.store(MemOp::Str, w.v, Base::State, self.st.published + 4 * slot);
        }
    }

    /// The word of a value's definition.
    fn def(&mut self, v: Value) -> Result<W, ThumbError> {
        let (p, fp, st) = (self.p, self.fp, self.st);
        let fr = fp.frac[v.index()];
        let rb = self.bound_of(v);
        let f = |x: &Value| fp.frac[x.index()];
        let real = |x: &Value| matches!(p.values[x.index()].ty, Ty::Real(_));
        let op = p.values[v.index()].op.clone();
        Ok(match op {
            Op::Const(_) | Op::Param(_) | Op::BoolConst(_) | Op::Variant(..) => self.word(v),
            Op::Sensor(s) => {
                let x = self.sensors[s.index()];
                let w = self.convert(x, fp.sensor_frac[s.index()], fr);
                W {
                    v: w.v,
                    b: w.b.min(rb),
                }
            }
            Op::Deriv(s, 2) if self.d2_parts[s.index()].is_some() => {
                let (d1, e) = self.d2_parts[s.index()].expect("checked");
                let (k, fk) = fp.deriv_gain[1];
                let sh = fr - (fp.sensor_frac[s.index()] + fk);
                let kv = self.movi(k);
                let a = self.smull(d1.v, kv);
                let kv = self.movi(k);
                let b = self.smull(e.v, kv);
                let diff = self.add64(a, b, true);
                self.round64(diff, sh, rb)
            }
            Op::Deriv(s, order) => {
                let d = self.derivs[s.index()][order as usize - 1].ok_or_else(|| {
                    ThumbError::Unsupported(format!("a derivative of order {order}"))
                })?;
                let (k, fk) = fp.deriv_gain[order as usize - 1];
                let e = fr - (fp.sensor_frac[s.index()] + fk);
                let kind = if d.b.saturating_mul(k.unsigned_abs() as u64) < LIM {
                    MulKind::Muls(0, 0)
                } else {
                    MulKind::Wide
                };
                self.mul(d, 0, Operand::Const(k), 0, e, kind, rb)
            }
            Op::State(s) => {
                let x = self.load(MemOp::Ldr, Base::State, st.states + 4 * s.index());
                let (lo, hi) = fp.state_raw_range[s.index()];
                let b = (lo as i64).unsigned_abs().max((hi as i64).unsigned_abs());
                self.convert(W { v: x, b }, fp.state_frac[s.index()], fr)
            }
            Op::Mode(m) => W {
                v: self.load(MemOp::Ldrb, Base::State, st.modes + m.index()),
                b: rb,
            },
            Op::Edge(e) => W {
                v: self.load(MemOp::Ldrb, Base::State, st.edges + e.index()),
                b: 1,
            },
            Op::Neg(x) => {
                let w = self.word(x);
                let n = self.neg(w);
                self.round(n, fr - f(&x))
            }
            Op::Not(x) => {
                let w = self.word(x);
                let n = self.unary(AluOp::Rsb, w.v);
                W {
                    v: self.addi(false, n, 1),
                    b: 1,
                }
            }
            Op::Arith(o, x, y) => match o {
                ArithOp::Add | ArithOp::Sub => {
                    let (a, b) = (self.word(x), self.word(y));
                    self.add(a, f(&x), b, f(&y), fr, o == ArithOp::Sub, rb)
                }
                ArithOp::Mul => {
                    let kind = fp.mul_kind[v.index()].unwrap_or(MulKind::Wide);
                    if self.is_const(y) {
                        let a = self.word(x);
                        self.mul(
                            a,
                            f(&x),
                            Operand::Const(fp.consts[y.index()]),
                            f(&y),
                            fr,
                            kind,
                            rb,
                        )
                    } else if self.is_const(x) {
                        // The plan's shifts are in operand order: (constant, variable) here.
                        let kind = match kind {
                            MulKind::Muls(sc, sv) => MulKind::Muls(sv, sc),
                            k => k,
                        };
                        let a = self.word(y);
                        self.mul(
                            a,
                            f(&y),
                            Operand::Const(fp.consts[x.index()]),
                            f(&x),
                            fr,
                            kind,
                            rb,
                        )
                    } else {
                        let (a, b) = (self.word(x), self.word(y));
                        self.mul(a, f(&x), Operand::Word(b), f(&y), fr, kind, rb)
                    }
                }
                ArithOp::Div => match fp.recip[v.index()] {
                    Some((r, fr_r)) => {
                        let kind = fp.mul_kind[v.index()].unwrap_or(MulKind::Wide);
                        let a = self.word(x);
                        self.mul(a, f(&x), Operand::Const(r), fr_r, fr, kind, rb)
                    }
                    None => {
                        let (a, b) = (self.word(x), self.word(y));
                        let iv = fp.ranges.values[y.index()];
                        let scale = 2f64.powi(f(&y));
                        let nonzero = iv.lo * scale > 2.0 || iv.hi * scale < -2.0;
                        if !nonzero || rb >= LIM {
                            return Err(ThumbError::Unsupported(
                                "division by a run-time value whose range contains 0 (use the C backend, or clamp the divisor away from 0)"
                                    .into(),
                            ));
                        }
                        // The divisor's planned pre-shift (`fixed::div_shifted`).
                        let sh = fp.div_shift[v.index()].min(31);
                        if sh == 0 {
                            return self.div(a, b, fr - f(&x) + f(&y), rb);
                        }
                        let shifted = (iv.lo * scale / 2f64.powi(sh as i32) > 2.0)
                            || (iv.hi * scale / 2f64.powi(sh as i32) < -2.0);
                        // The quotient by the floored divisor is larger by at most
                        // `2^(b+1) / min |y|` relatively (the planner keeps it below 2^31).
                        let ymin = (iv.lo * scale).abs().min((iv.hi * scale).abs());
                        let grow = (rb as f64 * 2f64.powi(sh as i32 + 1) / ymin).ceil() + 1.0;
                        let rb2 =
                            rb.saturating_add(if grow.is_finite() { grow as u64 } else { LIM });
                        if !shifted || rb2 >= LIM {
                            return Err(ThumbError::Unsupported(
                                "a division whose shifted divisor may be 0 or whose quotient may not fit"
                                    .into(),
                            ));
                        }
                        let bs = self.floor_shr(b, sh as i32);
                        self.div(a, bs, fr - f(&x) + f(&y) - sh as i32, rb2)?
                    }
                },
            },
            Op::Cmp(o @ (CmpOp::Eq | CmpOp::Ne), x, y)
                if !real(&x) && (self.is_zero_word(x) || self.is_zero_word(y)) =>
            {
                // A truth value or mode against 0: `RSBS t, a, #0` sets C exactly when
                // a = 0, so `ADCS t, a` leaves C; `a ≠ 0` is the sign of `-a | a`.
                let a = if self.is_zero_word(y) { x } else { y };
                let a = self.word(a).v;
                let t = self.unary(AluOp::Rsb, a);
                let v = if o == CmpOp::Eq {
                    self.alu2(AluOp::Adc, t, a)
                } else {
                    let t = self.alu2(AluOp::Orr, t, a);
                    self.sh(Shift::Lsr, t, 31)
                };
                W { v, b: 1 }
            }
            Op::Cmp(o, x, y) => match (fp.exact_const(x), fp.exact_const(y)) {
                (_, Some(k)) if real(&x) => {
                    let a = self.word(x);
                    self.cmp_const(o, a, f(&x), k, false)
                }
                (Some(k), _) if real(&y) => {
                    let a = self.word(y);
                    self.cmp_const(o, a, f(&y), k, true)
                }
                _ => {
                    let (a, b) = (self.word(x), self.word(y));
                    self.cmp(o, a, f(&x), b, f(&y))
                }
            },
            Op::And(x, y) | Op::Or(x, y) if self.fused[x.index()] || self.fused[y.index()] => {
                // `d = 0; if !(x op y) goto done; d = 1; done:` with the operands as
                // compare-and-branch chains.
                let d = self.movi(0);
                let done = self.label();
                self.branch_op(v, false, done)?;
                self.push(M::Movi { d, imm: 1 });
                self.push(M::Label(done));
                W { v: d, b: 1 }
            }
            Op::And(x, y) | Op::Or(x, y) => {
                let (a, b) = (self.word(x), self.word(y));
                let op = if matches!(op, Op::And(..)) {
                    AluOp::And
                } else {
                    AluOp::Orr
                };
                W {
                    v: self.alu2(op, a.v, b.v),
                    b: 1,
                }
            }
            Op::Select(c, x, y) => {
                let cw = self.word(c);
                let (a, b) = (self.word(x), self.word(y));
                let (a, b) = if real(&v) {
                    (self.convert(a, f(&x), fr), self.convert(b, f(&y), fr))
                } else {
                    (a, b)
                };
                self.select(cw.v, a, b)
            }
            Op::Call(func, x, y) => {
                let a = self.word(x);
                let fa = f(&x);
                match func {
                    Builtin::Abs => {
                        let neg = self.neg(a);
                        let n = self.round(neg, fr - fa);
                        let pos = self.convert(a, fa, fr);
                        let c = self.sh(Shift::Lsr, a.v, 31);
                        let r = self.select(c, n, pos);
                        W { v: r.v, b: rb }
                    }
                    Builtin::Min | Builtin::Max => {
                        let (b, fb) = match y {
                            Some(y) => (self.word(y), f(&y)),
                            None => (a, fa),
                        };
                        let cop = if func == Builtin::Min {
                            CmpOp::Le
                        } else {
                            CmpOp::Ge
                        };
                        let c = self.cmp(cop, a, fa, b, fb);
                        let (ca, cb) = (self.convert(a, fa, fr), self.convert(b, fb, fr));
                        let r = self.select(c.v, ca, cb);
                        W { v: r.v, b: rb }
                    }
                    Builtin::Exp => self.exp(a, fa, fr, rb),
                    Builtin::Sqrt => self.sqrt(a, fa, fr, rb),
                }
            }
        })
    }

    /// [`fx::div`] for a divisor that cannot be 0 and a quotient bounded by `rb < 2^31`:
    /// `trunc(x · 2^k / y)` by restoring division, one quotient bit per step, unrolled
    /// (`LSLS` feeds the next dividend bit into C, `ADCS` shifts it into the remainder,
    /// `SUBS` trial-subtracts, `ADCS` shifts the quotient bit in: 6 cycles a bit, the same on
    /// both paths). Signs are taken off first and put back on the quotient.
    ///
    /// [`fx::div`]: tactus_runtime::fixed::div
    fn div(&mut self, x: W, y: W, k: i32, rb: u64) -> Result<W, ThumbError> {
        let nb = (64 - rb.leading_zeros()) as i32; // quotient bits
                                                   // The divisor's bound once scaled for k < 0.
        let d_bound = if k >= 0 { y.b } else { shl_bound(y.b, -k) };
        if (k >= 0 || -k <= 31) && d_bound < LIM {
            let (steps, _) = crate::fixed::division_cycles(nb, crate::fixed::bits_of(d_bound));
            if steps > 0 {
                return Ok(self.sio_div(x, y, k, rb, steps));
            }
        }
        let abs = |this: &mut Self, w: V| -> (V, V) {
            let m = this.sh(Shift::Asr, w, 31);
            let t = this.alu2(AluOp::Eor, w, m);
            (this.addsub(true, t, m), m)
        };
        let (ax, mx) = abs(self, x.v);
        let (ay, my) = abs(self, y.v);
        // Dividend N = |x|·2^k (k ≥ 0), divisor D = |y| (or |y|·2^-k for k < 0).
        let (d, k) = if k >= 0 {
            (ay, k)
        } else if -k <= 31 && shl_bound(y.b, -k) < LIM {
            (self.sh(Shift::Lsl, ay, (-k) as u8), 0)
        } else {
            return Err(ThumbError::Unsupported(
                "a division whose divisor must be scaled beyond 32 bits".into(),
            ));
        };
        // Remainder starts at N >> nb (< D because the quotient is below 2^nb).
        let r = if nb >= k {
            if nb - k == 0 {
                let r = self.nv();
                self.push(M::Mov { d: r, s: ax });
                r
            } else if nb - k >= 32 {
                self.movi(0)
            } else {
                self.sh(Shift::Lsr, ax, (nb - k) as u8)
            }
        } else if k - nb <= 31 {
            self.sh(Shift::Lsl, ax, (k - nb) as u8)
        } else {
            return Err(ThumbError::Unsupported(
                "a division scaled by more than 2^31".into(),
            ));
        };
        // The low nb bits of N, top-aligned: |x| << (k + 32 - nb).
        let sh = k + 32 - nb;
        let feed = if sh >= 32 {
            self.movi(0)
        } else if sh == 0 {
            let f = self.nv();
            self.push(M::Mov { d: f, s: ax });
            f
        } else {
            self.sh(Shift::Lsl, ax, sh as u8)
        };
        let q = self.movi(0);
        let t = self.nv();
        for _ in 0..nb {
            self.push(M::Sh {
                op: Shift::Lsl,
                d: feed,
                m: feed,
                imm: 1,
            });
            self.push(M::Alu2 {
                op: AluOp::Adc,
                d: r,
                a: r,
                m: r,
            });
            self.push(M::AddSub {
                sub: true,
                d: t,
                a: r,
                b: d,
            });
            let skip = self.label();
            self.push(M::Bc(Cond::Lo, skip));
            self.push(M::Mov { d: r, s: t });
            self.push(M::Label(skip));
            self.push(M::Alu2 {
                op: AluOp::Adc,
                d: q,
                a: q,
                m: q,
            });
        }
        // Sign: q = (q ^ m) - m with m = sign(x) ^ sign(y).
        let m = self.alu2(AluOp::Eor, mx, my);
        let t = self.alu2(AluOp::Eor, q, m);
        Ok(W {
            v: self.addsub(true, t, m),
            b: rb,
        })
    }

    /// [`fx::div`] on the RP2040's SIO hardware divider (datasheet 2.3.1.5: unsigned
    /// dividend at `0xd000_0060`, divisor at `0x064`, quotient `0x070` and remainder `0x074`
    /// valid 8 cycles after the last operand write): `trunc(|x|·2^k / |y|)` by long division
    /// in digits of `s = 32 − L` bits for a divisor of `L` bits, `steps` hardware divisions
    /// ([`crate::fixed::sio_division_steps`]). The first divides the top of the dividend
    /// (below `|y|·2^s`, since the quotient is below `2^nb` with `nb ≤ steps·s`); each later
    /// one divides the remainder with the next `s` dividend bits appended, whose quotient is
    /// the next digit. Unsigned throughout; the sign is put back at the end, so the quotient
    /// truncates toward zero as [`fx::div`] does. The divisor is written once: writing the
    /// dividend starts the next division with the divisor register unchanged.
    ///
    /// The divider is per core, and the update runs only from the firmware's sample
    /// interrupt, which does not nest (and from host calls on an idle core): nothing else
    /// uses the divider between our writes and reads, so its state needs no saving
    /// (the pico-sdk saves it only because its interrupts may interrupt a division).
    ///
    /// [`fx::div`]: tactus_runtime::fixed::div
    fn sio_div(&mut self, x: W, y: W, k: i32, rb: u64, steps: u32) -> W {
        const SIO_BASE: i32 = 0xd000_0000u32 as i32;
        const UDIVIDEND: u16 = 0x060;
        const UDIVISOR: u16 = 0x064;
        const QUOTIENT: u16 = 0x070;
        const REMAINDER: u16 = 0x074;
        let abs = |this: &mut Self, w: V| -> (V, V) {
            let m = this.sh(Shift::Asr, w, 31);
            let t = this.alu2(AluOp::Eor, w, m);
            (this.addsub(true, t, m), m)
        };
        let (ax, mx) = abs(self, x.v);
        let (ay, my) = abs(self, y.v);
        let (d, d_bound, k) = if k >= 0 {
            (ay, y.b, k)
        } else {
            (self.sh(Shift::Lsl, ay, (-k) as u8), shl_bound(y.b, -k), 0)
        };
        let s = 32 - crate::fixed::bits_of(d_bound);
        let low = (steps as i32 - 1) * s; // dividend bits below the first step's
                                          // First dividend: |x|·2^k >> low.
        let e = k - low;
        let first = if e == 0 {
            ax
        } else if e > 0 {
            self.sh(Shift::Lsl, ax, e.min(31) as u8)
        } else if -e >= 32 {
            self.movi(0)
        } else {
            self.sh(Shift::Lsr, ax, (-e) as u8)
        };
        // The low `low` dividend bits, top-aligned: |x| << (k + 32 − low) (none if ≥ 32).
        let fsh = k + 32 - low;
        let mut feed = if steps > 1 && fsh < 32 {
            Some(if fsh == 0 {
                ax
            } else {
                self.sh(Shift::Lsl, ax, fsh as u8)
            })
        } else {
            None
        };
        let sio = self.movi(SIO_BASE);
        self.store(MemOp::Str, d, Base::V(sio), UDIVISOR as usize);
        self.store(MemOp::Str, first, Base::V(sio), UDIVIDEND as usize);
        // While the divider works (DIVIDER_LATENCY cycles): the next dividend digit from
        // the feed, the previous digits shifted up; NOPs for the rest of the wait. Every
        // instruction here is 1 cycle (spill code the allocator may add only waits longer).
        let wait = timing_divider_latency() as usize;
        let mut digit = None;
        let mut busy = 0;
        let next_digit = |this: &mut Self, feed: &mut Option<V>, busy: &mut usize| {
            if let Some(f) = *feed {
                let dg = this.sh(Shift::Lsr, f, (32 - s) as u8);
                *feed = Some(this.sh(Shift::Lsl, f, s as u8));
                *busy += 2;
                Some(dg)
            } else {
                None
            }
        };
        if steps > 1 {
            digit = next_digit(self, &mut feed, &mut busy);
        }
        for _ in busy..wait {
            self.push(M::Nop);
        }
        let mut q = self.load(MemOp::Ldr, Base::V(sio), QUOTIENT as usize);
        for step in 1..steps {
            let r = self.load(MemOp::Ldr, Base::V(sio), REMAINDER as usize);
            let r = self.sh(Shift::Lsl, r, s as u8);
            let dv = match digit {
                Some(dg) => self.alu2(AluOp::Orr, r, dg),
                None => r,
            };
            self.store(MemOp::Str, dv, Base::V(sio), UDIVIDEND as usize);
            let qs = self.sh(Shift::Lsl, q, s as u8);
            busy = 1;
            digit = if step + 1 < steps {
                next_digit(self, &mut feed, &mut busy)
            } else {
                None
            };
            for _ in busy..wait {
                self.push(M::Nop);
            }
            let dq = self.load(MemOp::Ldr, Base::V(sio), QUOTIENT as usize);
            q = self.alu2(AluOp::Orr, qs, dq);
        }
        // Sign: q = (q ^ m) - m with m = sign(x) ^ sign(y).
        let m = self.alu2(AluOp::Eor, mx, my);
        let t = self.alu2(AluOp::Eor, q, m);
        W {
            v: self.addsub(true, t, m),
            b: rb,
        }
    }

    /// [`fx::exp`] of the word `x` (format `fx_`) into `fr` fraction bits; `rb` bounds the
    /// result as the range analysis sees it. Straight-line apart from the shortcuts: words
    /// beyond the limits of [`prim::exp_limits`] give 0 or saturate (compared only where
    /// `x`'s bound reaches them); otherwise `k` by one `MULS`, `r` in Q32 by two `MULS`
    /// modulo 2^32, eight Horner steps of a 32×32→64 product's high word (four `MULS` on the
    /// 16-bit halves; `r`'s halves taken once), and the final `P·2^(k + fr − 30)` as a
    /// rounding right shift by the register `30 − fr − k ∈ [0, 32]` (`−1` only where `x`'s
    /// bound reaches it: then `2P`, saturated).
    ///
    /// [`fx::exp`]: tactus_runtime::fixed::exp
    fn exp(&mut self, x: W, fx_: i32, fr: i32, rb: u64) -> W {
        use tactus_runtime::fixed as fx;
        let (xlo, xhi) = prim::exp_limits(fx_, fr);
        // The reach of x: [-lo_reach, hi_reach].
        let (lo_reach, hi_reach) = (x.b.min(LIM) as i64, x.b.min(LIM - 1) as i64);
        // The result may exceed the interval's bound by exp's relative error (2^-28).
        let b = if rb >= LIM {
            LIM
        } else {
            (rb + (rb >> 27) + 2).min(LIM)
        };
        if xlo > hi_reach {
            return W {
                v: self.movi(0),
                b: 0,
            };
        }
        if xhi < -lo_reach {
            return W {
                v: self.movi(i32::MAX),
                b,
            };
        }
        let d = self.nv();
        let done = self.label();
        let shortcut = |this: &mut Self, limit: i64, ok: Cond, value: i32| {
            let k = this.movi(limit as i32);
            this.push(M::Cmp { a: x.v, b: k });
            let ok_l = this.label();
            this.push(M::Bc(ok, ok_l));
            this.push(M::Movi { d, imm: value });
            this.push(M::B(done));
            this.push(M::Label(ok_l));
        };
        if xhi < hi_reach {
            shortcut(self, xhi, Cond::Le, i32::MAX);
        }
        if xlo > -lo_reach {
            shortcut(self, xlo, Cond::Ge, 0);
        }
        // Within the limits |k| <= 64, |t| < 2^14.
        let t = if fx_ >= 8 {
            match (fx_ - 8).min(31) {
                0 => x.v,
                s => self.sh(Shift::Asr, x.v, s as u8),
            }
        } else if 8 - fx_ <= 31 {
            self.sh(Shift::Lsl, x.v, (8 - fx_) as u8)
        } else {
            self.movi(0) // only x = 0 is within the limits
        };
        let c = self.movi(fx::EXP_INV_LN2_Q16);
        let tk = self.alu2(AluOp::Mul, t, c);
        let k = self.rshr(W { v: tk, b: LIM - 2 }, 24).v;
        // r = X − k·L − round(k·D / 2^24), modulo 2^32.
        let big_x = if fx_ > 32 {
            Some(self.sh(Shift::Asr, x.v, (fx_ - 32) as u8))
        } else if fx_ == 32 {
            Some(x.v)
        } else if fx_ > 0 {
            Some(self.sh(Shift::Lsl, x.v, (32 - fx_) as u8))
        } else {
            None
        };
        let dl = self.movi(fx::EXP_LN2_LO_Q56);
        let kd = self.alu2(AluOp::Mul, k, dl);
        let corr = self.rshr(W { v: kd, b: LIM - 2 }, 24).v;
        let l = self.movi(fx::EXP_LN2_Q32 as i32);
        let kl = self.alu2(AluOp::Mul, k, l);
        let kl = self.addsub(false, kl, corr);
        let r = match big_x {
            Some(bx) => self.addsub(true, bx, kl),
            None => self.unary(AluOp::Rsb, kl),
        };
        // P = exp(r) in Q30 by Horner.
        let rl = self.nv();
        self.push(M::Uxth { d: rl, m: r });
        let rh = self.sh(Shift::Asr, r, 16);
        let mut p = self.movi(fx::EXP_COEFFS_Q30[8]);
        for n in (0..8).rev() {
            let hi = self.mulhi_halves(p, rl, rh);
            let cn = self.movi(fx::EXP_COEFFS_Q30[n]);
            p = self.addsub(false, hi, cn);
        }
        // P·2^(k + fr − 30) = P / 2^s, s = 30 − fr − k.
        let c = self.movi(30 - fr);
        let s = self.addsub(true, c, k);
        let kmax = fx::exp_k(xhi.min(hi_reach) as i32, fx_);
        let normal = self.label();
        if kmax + fr as i64 >= 31 {
            // s = −1: 2P, saturated (P < 2^31, so 2P as a word is negative when it overflows).
            self.push(M::Bc(Cond::Pl, normal));
            let two = self.sh(Shift::Lsl, p, 1);
            self.push(M::Mov { d, s: two });
            self.push(M::Bc(Cond::Pl, done));
            self.push(M::Movi { d, imm: i32::MAX });
            self.push(M::B(done));
        }
        self.push(M::Label(normal));
        // round(P / 2^s) = ((2P >> s) + 1) >> 1, unsigned: 2P < 2^32.
        let two = self.sh(Shift::Lsl, p, 1);
        let q = self.alu2(AluOp::Lsr, two, s);
        let q = self.addi(false, q, 1);
        let q = self.sh(Shift::Lsr, q, 1);
        self.push(M::Mov { d, s: q });
        self.push(M::Label(done));
        W { v: d, b }
    }

    /// [`fx::sqrt`] of the word `x` (format `fx_`) into `fr` fraction bits: 0 for `x ≤ 0`;
    /// with `M = x·2^e` (`e`, `post` as the definition computes them), the integer root
    /// `s = floor(sqrt(M))` and remainder `M − s²` digit by digit (two radicand bits per
    /// step, unrolled: `ADCS` shifts the next bits in from a feed register, `SUBS` trial-
    /// subtracts `4s + 1`, `ADCS` shifts the root bit in; about 10 cycles a root bit). Then
    /// `floor(2·sqrt(M)) = 2s + (rem > s)`, rounded by `1 + post` bits; for `post = 0` that is
    /// `s + (rem > s)`, and words above the compile-time limit `(2^62 − 2^31) >> e` saturate
    /// (as [`prim::sqrt`]'s `tx_sqrt`). The root has at most 31 bits (`M < 2^62`): only its
    /// last step can see a 33-bit remainder, taken from the carry.
    ///
    /// [`fx::sqrt`]: tactus_runtime::fixed::sqrt
    fn sqrt(&mut self, x: W, fx_: i32, fr: i32, rb: u64) -> W {
        let mut e = 2 * fr - fx_;
        let mut post = 0;
        if e < 0 {
            let p = (-e + 1) / 2;
            e += 2 * p;
            post = p;
        }
        let hi_reach = x.b.min(LIM - 1) as i64;
        if hi_reach <= 0 {
            return W {
                v: self.movi(0),
                b: 0,
            };
        }
        let b = rb.min(LIM);
        // Words above xs saturate (post = 0 only).
        let xs: i64 = if post > 0 {
            i64::MAX
        } else if e >= 62 {
            0
        } else {
            (((1u64 << 62) - (1u64 << 31)) >> e) as i64
        };
        let d = self.nv();
        let done = self.label();
        // x <= 0 → 0.
        let pos = self.label();
        self.push(M::CmpI { a: x.v, imm: 0 });
        self.push(M::Bc(Cond::Gt, pos));
        self.push(M::Movi { d, imm: 0 });
        self.push(M::B(done));
        self.push(M::Label(pos));
        if xs < hi_reach {
            if xs == 0 {
                self.push(M::Movi { d, imm: i32::MAX });
                self.push(M::B(done));
                self.push(M::Label(done));
                return W { v: d, b: LIM - 1 };
            }
            let k = self.movi(xs as i32);
            self.push(M::Cmp { a: x.v, b: k });
            let ok = self.label();
            self.push(M::Bc(Cond::Le, ok));
            self.push(M::Movi { d, imm: i32::MAX });
            self.push(M::B(done));
            self.push(M::Label(ok));
        }
        // M = x·2^e < 2^62 (0 < x < 2^31 and x <= xs): `pairs` pairs of bits from the top;
        // the feed register holds M's top 32 bits, top-aligned (x has at most 62 − e bits).
        let bits = (31 + e).min(62);
        let pairs = (bits + 1) / 2;
        let feed = self.nv();
        match 32 - 2 * pairs + e {
            0 => self.push(M::Mov { d: feed, s: x.v }),
            sh => self.push(M::Sh {
                op: Shift::Lsl,
                d: feed,
                m: x.v,
                imm: sh as u8,
            }),
        }
        let rem = self.movi(0);
        let root = self.movi(0);
        let t = self.nv();
        let u = self.nv();
        for j in 1..=pairs {
            // Bits fed so far: 2(j-1); the feed register holds 32 of them.
            let from_feed = 2 * (j - 1) < 32;
            self.push(M::Sh {
                op: Shift::Lsl,
                d: t,
                m: root,
                imm: 2,
            });
            self.push(M::AddSubI {
                sub: false,
                d: t,
                a: t,
                imm: 1,
            });
            if from_feed {
                for _ in 0..2 {
                    self.push(M::Sh {
                        op: Shift::Lsl,
                        d: feed,
                        m: feed,
                        imm: 1,
                    });
                    self.push(M::Alu2 {
                        op: AluOp::Adc,
                        d: rem,
                        a: rem,
                        m: rem,
                    });
                }
            } else {
                self.push(M::Sh {
                    op: Shift::Lsl,
                    d: rem,
                    m: rem,
                    imm: 2,
                });
            }
            let (skip, next) = (self.label(), self.label());
            let force = self.label();
            if j == 31 {
                // rem·4 may have 33 bits: its carry forces the subtraction (the difference
                // fits 32 bits again).
                self.push(M::Bc(Cond::Hs, force));
            }
            // u = rem − t; C (no borrow) = rem >= t: keep u, and shift C into the root.
            self.push(M::AddSub {
                sub: true,
                d: u,
                a: rem,
                b: t,
            });
            self.push(M::Bc(Cond::Lo, skip));
            self.push(M::Mov { d: rem, s: u });
            self.push(M::Label(skip));
            self.push(M::Alu2 {
                op: AluOp::Adc,
                d: root,
                a: root,
                m: root,
            });
            if j == 31 {
                self.push(M::B(next));
                self.push(M::Label(force));
                self.push(M::AddSub {
                    sub: true,
                    d: rem,
                    a: rem,
                    b: t,
                });
                self.push(M::AddSub {
                    sub: false,
                    d: root,
                    a: root,
                    b: root,
                });
                self.push(M::AddSubI {
                    sub: false,
                    d: root,
                    a: root,
                    imm: 1,
                });
            }
            self.push(M::Label(next));
        }
        // c = (rem > s): after `CMP s, rem`, LO.
        if post == 0 {
            self.push(M::Mov { d, s: root });
            self.push(M::Cmp { a: root, b: rem });
            self.push(M::Bc(Cond::Hs, done));
            self.push(M::AddSubI {
                sub: false,
                d,
                a: d,
                imm: 1,
            });
        } else {
            let r2 = self.addsub(false, root, root);
            let c_done = self.label();
            self.push(M::Cmp { a: root, b: rem });
            self.push(M::Bc(Cond::Hs, c_done));
            self.push(M::AddSubI {
                sub: false,
                d: r2,
                a: r2,
                imm: 1,
            });
            self.push(M::Label(c_done));
            let r = self.rshr(W { v: r2, b: 1 << 17 }, 1 + post);
            self.push(M::Mov { d, s: r.v });
        }
        self.push(M::Label(done));
        W { v: d, b }
    }

    /// `floor(p · r / 2^32)` for `0 ≤ p < 2^31` and the word `r` given as its halves
    /// `rl = r & 0xFFFF`, `rh = r >> 16` (arithmetic): the exact 64-bit product from four
    /// 16×16 `MULS`, high word kept.
    fn mulhi_halves(&mut self, p: V, rl: V, rh: V) -> V {
        let pl = self.nv();
        self.push(M::Uxth { d: pl, m: p });
        let ph = self.sh(Shift::Lsr, p, 16);
        let lo = self.alu2(AluOp::Mul, pl, rl);
        let hi = self.alu2(AluOp::Mul, ph, rh);
        let m1 = self.alu2(AluOp::Mul, pl, rh);
        let m2 = self.alu2(AluOp::Mul, ph, rl);
        self.add_cross_terms((lo, hi), m1, m2).1
    }

    /// `c ? a : b` for a 0/1 word `c`, branch-free: `b ^ ((a ^ b) & -c)`.
    fn select(&mut self, c: V, a: W, b: W) -> W {
        let m = self.unary(AluOp::Rsb, c);
        // One side a known 0: `a & -c` or `b & ~(-c)` (`BICS`).
        let b_zero = self.konst.get(&b.v) == Some(&0);
        if b_zero || self.konst.get(&a.v) == Some(&0) {
            let (op, keep) = if b_zero {
                (AluOp::And, a)
            } else {
                (AluOp::Bic, b)
            };
            return W {
                v: self.alu2(op, keep.v, m),
                b: keep.b,
            };
        }
        let t = self.alu2(AluOp::Eor, a.v, b.v);
        let t = self.alu2(AluOp::And, t, m);
        W {
            v: self.alu2(AluOp::Eor, t, b.v),
            b: a.b.max(b.b),
        }
    }

    /// A 0/1 word from the flags of `CMP a, b` (a diamond).
    fn set_flag(&mut self, cond: Cond) -> V {
        let d = self.nv();
        let (yes, done) = (self.label(), self.label());
        self.push(M::Bc(cond, yes));
        self.push(M::Movi { d, imm: 0 });
        self.push(M::B(done));
        self.push(M::Label(yes));
        self.push(M::Movi { d, imm: 1 });
        self.push(M::Label(done));
        d
    }

    /// `a OP b` of two 32-bit words on the same grid.
    fn cmp32(&mut self, o: CmpOp, a: W, b: W) -> W {
        let v = match o {
            CmpOp::Eq => {
                let d = self.addsub(true, a.v, b.v);
                let n = self.unary(AluOp::Rsb, d);
                self.alu2(AluOp::Adc, d, n)
            }
            CmpOp::Ne => {
                let d = self.addsub(true, a.v, b.v);
                let n = self.unary(AluOp::Rsb, d);
                let t = self.alu2(AluOp::Orr, n, d);
                self.sh(Shift::Lsr, t, 31)
            }
            _ if a.b + b.b < LIM => {
                // No overflow: the sign of the difference decides.
                let (x, y, invert) = match o {
                    CmpOp::Lt => (a, b, false),
                    CmpOp::Gt => (b, a, false),
                    CmpOp::Ge => (a, b, true),
                    _ => (b, a, true), // Le: !(b < a)
                };
                let d = self.addsub(true, x.v, y.v);
                let d = if invert { self.unary(AluOp::Mvn, d) } else { d };
                self.sh(Shift::Lsr, d, 31)
            }
            _ => {
                self.push(M::Cmp { a: a.v, b: b.v });
                self.set_flag(cond_of(o))
            }
        };
        W { v, b: 1 }
    }

    /// Two words of formats `fa`, `fb` on the finer grid, for an exact comparison: as 32-bit
    /// words when the coarser one shifted left provably fits, else with their left shifts
    /// for [`Sel::scaled64`].
    fn common_grid(&mut self, a: W, fa: i32, b: W, fb: i32) -> Grid {
        let (d_a, d_b) = match fa.cmp(&fb) {
            Ordering::Equal => (0, 0),
            Ordering::Greater => (0, fa - fb),
            Ordering::Less => (fb - fa, 0),
        };
        let fits = |w: W, d: i32| d <= 31 && shl_bound(w.b, d) < LIM;
        if !(fits(a, d_a) && fits(b, d_b)) {
            return Grid::Wide((a, d_a), (b, d_b));
        }
        let mut up = |w: W, d: i32| {
            if d > 0 {
                W {
                    v: self.sh(Shift::Lsl, w.v, d as u8),
                    b: shl_bound(w.b, d),
                }
            } else {
                w
            }
        };
        let a = up(a, d_a);
        Grid::Words(a, up(b, d_b))
    }

    /// An ordered comparison (`<`, `<=`, `>`, `>=`) of two scaled words in 64 bits:
    /// `SUBS`/`SBCS` of `x − y` (or `y − x`) leave N and V of the 64-bit difference; returns
    /// the condition under which the comparison holds.
    fn cmp64_ordered(&mut self, o: CmpOp, a: (W, i32), b: (W, i32)) -> Cond {
        let x = self.scaled64(a.0, a.1);
        let y = self.scaled64(b.0, b.1);
        let (p, q, cond) = match o {
            CmpOp::Lt => (x, y, Cond::Lt),
            CmpOp::Ge => (x, y, Cond::Ge),
            CmpOp::Gt => (y, x, Cond::Lt),
            _ => (y, x, Cond::Ge),
        };
        let _ = self.add64(p, q, true);
        cond
    }

    /// `w · 2^d` as a 64-bit (lo, hi) pair for a comparison. When the shift is 32 or more
    /// only the sign of the scaled word matters (the other word is below 2^31): it becomes
    /// `sign(w) · 2^32`, as the definition's reduction does.
    fn scaled64(&mut self, w: W, d: i32) -> (V, V) {
        if d <= 31 {
            self.shl64(w.v, d)
        } else {
            let s = self.sh(Shift::Asr, w.v, 31);
            let pos = self.unary(AluOp::Rsb, w.v);
            let pos = self.sh(Shift::Lsr, pos, 31); // 1 when w > 0
            let sign = self.alu2(AluOp::Orr, s, pos); // -1, 0 or 1
            let lo = self.movi(0);
            (lo, sign)
        }
    }

    /// [`fx::cmp`]: exact comparison of words in different formats.
    fn cmp(&mut self, o: CmpOp, a: W, fa: i32, b: W, fb: i32) -> W {
        if a.v == b.v && fa == fb {
            let holds = matches!(o, CmpOp::Eq | CmpOp::Le | CmpOp::Ge);
            return W {
                v: self.movi(holds as i32),
                b: 1,
            };
        }
        let (a, b) = match self.common_grid(a, fa, b, fb) {
            Grid::Words(a, b) => return self.cmp32(o, a, b),
            Grid::Wide(a, b) => (a, b),
        };
        let v = match o {
            CmpOp::Eq | CmpOp::Ne => {
                let x = self.scaled64(a.0, a.1);
                let y = self.scaled64(b.0, b.1);
                let l = self.alu2(AluOp::Eor, x.0, y.0);
                let h = self.alu2(AluOp::Eor, x.1, y.1);
                let t = self.alu2(AluOp::Orr, l, h);
                let n = self.unary(AluOp::Rsb, t);
                if o == CmpOp::Eq {
                    self.alu2(AluOp::Adc, t, n)
                } else {
                    let t = self.alu2(AluOp::Orr, n, t);
                    self.sh(Shift::Lsr, t, 31)
                }
            }
            _ => {
                let cond = self.cmp64_ordered(o, a, b);
                self.set_flag(cond)
            }
        };
        W { v, b: 1 }
    }

    /// [`fx::cmp_const`]: `x OP c` (or `c OP x`) as thresholds on the word grid.
    fn cmp_const(&mut self, o: CmpOp, x: W, fx_: i32, c: f64, const_left: bool) -> W {
        let (ge, gt) = prim::thresholds(fx_, c);
        let o = if const_left { o.mirrored() } else { o };
        let (lo, hi) = (i32::MIN as i64, i32::MAX as i64);
        // x >= t as a 0/1 word (constant outside the word range).
        let at_least = |this: &mut Self, t: i64, neg: bool| -> W {
            if t <= lo || t > hi {
                return W {
                    v: this.movi(((t <= lo) != neg) as i32),
                    b: 1,
                };
            }
            let t = t as i32;
            let k = W {
                v: this.movi(t),
                b: t.unsigned_abs() as u64,
            };
            this.cmp32(if neg { CmpOp::Lt } else { CmpOp::Ge }, x, k)
        };
        match o {
            CmpOp::Ge => at_least(self, ge, false),
            CmpOp::Lt => at_least(self, ge, true),
            CmpOp::Gt => at_least(self, gt, false),
            CmpOp::Le => at_least(self, gt, true),
            CmpOp::Eq | CmpOp::Ne => {
                if gt == ge + 1 && ge > lo && ge <= hi {
                    let k = W {
                        v: self.movi(ge as i32),
                        b: (ge as i32).unsigned_abs() as u64,
                    };
                    return self.cmp32(o, x, k);
                }
                let a = at_least(self, ge, false);
                let b = at_least(self, gt, true);
                let e = self.alu2(AluOp::And, a.v, b.v);
                let v = if o == CmpOp::Ne {
                    let n = self.unary(AluOp::Rsb, e);
                    self.addi(false, n, 1)
                } else {
                    e
                };
                W { v, b: 1 }
            }
        }
    }
}

/// A short source-level description of a condition value, for the listing and the WCET
/// report (`on hammer_hits_string`-style names come from the handler's span text).
fn describe(p: &Program, v: Value) -> String {
    let span = &p.values[v.index()].span;
    format!("condition v{} @{}..{}", v.0, span.start, span.end)
}

/// `r1` and `r2` on entry: the sensors and out pointers (virtual registers pre-coloured
/// by the allocator).
pub(crate) const ARG1: V = V(0);
pub(crate) const ARG2: V = V(1);
pub(crate) const FIRST_FREE: u32 = 2;

impl<'a> Sel<'a> {
    /// The body of `init`: zero the struct, then the initial states and modes.
    pub(crate) fn init_body(mut self) -> Selected {
        let (p, fp, st) = (self.p, self.fp, self.st);
        self.nv = FIRST_FREE;
        let z = self.movi(0);
        // Every word but the param block, which the firmware wrote before.
        let params = st.params / 4..st.params / 4 + fp.param_words.len();
        for w in (0..st.size / 4).filter(|w| !params.contains(w)) {
            self.store(MemOp::Str, z, Base::State, 4 * w);
        }
        for (i, &init) in fp.state_init.iter().enumerate() {
            if init != 0 {
                let k = self.movi(init);
                self.store(MemOp::Str, k, Base::State, st.states + 4 * i);
            }
        }
        for (i, md) in p.modes.iter().enumerate() {
            if md.init != 0 {
                let k = self.movi(md.init as i32);
                self.store(MemOp::Strb, k, Base::State, st.modes + i);
            }
        }
        Selected {
            code: self.code,
            nregs: self.nv,
            exclusive: Vec::new(),
        }
    }
}
