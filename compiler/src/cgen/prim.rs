//! The fixed-point primitives of [`tactus_runtime::fixed`] as C99 expressions.
//!
//! Each function here returns a C expression of type `int32_t` (comparisons: `int`, 0 or 1)
//! that computes exactly the bits of the corresponding `tactus_runtime::fixed` function,
//! with every format (fraction-bit count) baked in as a constant. The definition works in
//! `i128`; C99 has no 128-bit type, so every shape is first reduced on the compile-time
//! constants to one that fits `int64_t`/`uint64_t`:
//!
//! * a round-half-up right shift is `floor(v/2^m)` plus bit `m−1` of `v` ([`RUNTIME`]'s
//!   `tx_rshr`), which never overflows;
//! * a two-operand sum first floors its finer operand to the grid `g` of the coarser one
//!   (or one bit finer than the result, if that is coarser), which leaves the final
//!   round-half-up unchanged because `floor((floor(y)+c)/M) = floor((y+c)/M)` for integers
//!   `c`, `M`; a coarser operand shifted left by 32 or more only decides the saturation
//!   sign, so it is clamped to ±2 first;
//! * a comparison with a constant is an integer comparison with a threshold found on the
//!   word grid by [`tactus_runtime::fixed::cmp_const`] itself.
//!
//! Right shifts of negative numbers are implementation-defined in C99, so `tx_floor_shr`
//! floors through `~` (exact-width integers are two's complement by C99 7.18.1.1). Left
//! shifts of signed values are written as multiplications by powers of two. `sqrt`, `exp`
//! and division by a run-time value are `static inline` helpers in [`RUNTIME`].

use crate::ir::CmpOp;
use std::cmp::Ordering;
use tactus_runtime::fixed as fx;

/// Helper functions every generated source includes (all `static inline`, prefix `tx_`).
pub const RUNTIME: &str = r#"/* ---- fixed-point helpers: the bits of tactus_runtime::fixed, in int64_t ---- */

/* floor(v / 2^s) for 0 <= s <= 63 (no right shift of a negative value). */
static inline int64_t tx_floor_shr(int64_t v, int s) {
    return v < 0 ? ~(~v >> s) : v >> s;
}

/* Saturates to int32_t. */
static inline int32_t tx_sat(int64_t v) {
    return v > INT32_MAX ? INT32_MAX : v < INT32_MIN ? INT32_MIN : (int32_t)v;
}

/* floor(v / 2^m + 1/2) for m >= 1: round half up, never overflows. */
static inline int64_t tx_rshr(int64_t v, int m) {
    if (m >= 64) return 0;
    return tx_floor_shr(v, m) + (int64_t)(((uint64_t)v >> (m - 1)) & 1u);
}

/* v * 2^e saturated to int32_t, e >= 0. */
static inline int32_t tx_shl_sat(int64_t v, int e) {
    if (v == 0) return 0;
    if (e >= 32) return v > 0 ? INT32_MAX : INT32_MIN;
    if (v > (int64_t)(INT32_MAX >> e)) return INT32_MAX;
    if (v < -((int64_t)1 << (31 - e))) return INT32_MIN;
    return (int32_t)(v * ((int64_t)1 << e));
}

/* v * 2^e rounded half up and saturated to int32_t, any e. */
static inline int32_t tx_round(int64_t v, int e) {
    return e >= 0 ? tx_shl_sat(v, e) : tx_sat(tx_rshr(v, -e));
}

/* Clamps to [-2, 2] (a term shifted left by 32 or more only decides the sign). */
static inline int64_t tx_clamp2(int64_t v) {
    return v > 2 ? 2 : v < -2 ? -2 : v;
}

/* d * k * 2^e rounded half up and saturated, |d| < 2^47, without a 96-bit product. */
static inline int32_t tx_round_wide(int64_t d, int32_t k, int e) {
    int64_t dh = tx_floor_shr(d, 16);
    int64_t hi = dh * k, lo = (d - dh * 65536) * k; /* d*k = hi*2^16 + lo */
    int big = hi >= ((int64_t)1 << 40) || hi <= -((int64_t)1 << 40);
    if (e <= -17) return tx_sat(tx_rshr(hi + tx_floor_shr(lo, 16), -e - 16));
    if (big) return hi > 0 ? INT32_MAX : INT32_MIN;
    return tx_round(hi * 65536 + lo, e);
}

/* The high part of x*y in units of 2^k (16 <= k <= 32) from three 16x16 partial products:
   xh*yh*2^(32-k) + floor(xh*yl / 2^(k-16)) + floor(xl*yh / 2^(k-16)). */
static inline int64_t tx_mul_high(int32_t x, int32_t y, int k) {
    /* Every partial product fits an int32_t (|xh| <= 2^15, 0 <= yl < 2^16): 32-bit
       multiplies, no 64-bit library call. (x - xl) / 65536 is exact, so it is x >> 16. */
    int32_t xl = (int32_t)((uint32_t)x & 0xffffu), yl = (int32_t)((uint32_t)y & 0xffffu);
    int32_t xh = (x - xl) / 65536, yh = (y - yl) / 65536;
    return (int64_t)(xh * yh) * ((int64_t)1 << (32 - k))
        + tx_floor_shr((int64_t)(xh * yl), k - 16) + tx_floor_shr((int64_t)(xl * yh), k - 16);
}

/* x*(y >> b) in units of 2^k (0 <= k <= 16) from two 16x16 partial products, y cut to
   ys = floor(y / 2^b): xh*ys*2^(16-k) + floor(xl*ys / 2^k). A planned program's ys is a
   signed 16-bit half: then both partial products fit an int32_t (|xh| <= 2^15,
   0 <= xl < 2^16, |ys| <= 2^15) and are 32-bit multiplies (two MULS on a Cortex-M0+, no
   64-bit multiply), floored in 32 bits; only their sum is formed in int64_t (a shift and an
   add). A wider ys (other words) takes the same sum in int64_t products, exact for any words
   (|xh*ys| <= 2^46). */
static inline int64_t tx_mul_32x16(int32_t x, int32_t y, int b, int k) {
    int32_t xl = (int32_t)((uint32_t)x & 0xffffu), xh = (x - xl) / 65536;
    int32_t ys = y < 0 ? ~(~y >> b) : y >> b, hi, lo;
    if (ys >= -32768 && ys <= 32767) {
        hi = xh * ys;
        lo = xl * ys;
        return (int64_t)hi * ((int64_t)1 << (16 - k)) + (lo < 0 ? ~(~lo >> k) : lo >> k);
    }
    return (int64_t)xh * ys * ((int64_t)1 << (16 - k)) + tx_floor_shr((int64_t)xl * ys, k);
}

/* x * 2^k / y truncated toward zero, saturated; y = 0 saturates to the sign of x. */
static inline int32_t tx_div(int32_t x, int32_t y, int k) {
    uint64_t ax, ay, q;
    int neg, big;
    if (y == 0) return x > 0 ? INT32_MAX : x < 0 ? INT32_MIN : 0;
    if (k < 0) {
        if (k <= -32) return 0;
        return (int32_t)((int64_t)x / ((int64_t)y * ((int64_t)1 << -k)));
    }
    if (x == 0) return 0;
    ax = (uint64_t)(x < 0 ? -(int64_t)x : (int64_t)x);
    ay = (uint64_t)(y < 0 ? -(int64_t)y : (int64_t)y);
    neg = (x < 0) != (y < 0);
    if (k >= 63) big = 1;
    else if (k >= 31) big = (ax << (k - 31)) >= ay;
    else big = (ax << k) >= (ay << 31);
    if (big) return neg ? INT32_MIN : INT32_MAX;
    q = (ax << k) / ay;
    return neg ? (int32_t)-(int64_t)q : (int32_t)q;
}

/* floor(sqrt(n)), digit by digit. */
static inline uint64_t tx_isqrt(uint64_t n) {
    uint64_t res = 0, one = (uint64_t)1 << 62;
    while (one > n) one >>= 2;
    while (one != 0) {
        if (n >= res + one) {
            n -= res + one;
            res = (res >> 1) + one;
        } else {
            res >>= 1;
        }
        one >>= 2;
    }
    return res;
}

/* sqrt(max(x, 0)) with the root of x * 2^e taken exactly, then shifted right by post
   (rounded half up); see tactus_runtime::fixed::sqrt. */
static inline int32_t tx_sqrt(int32_t x, int e, int post) {
    uint64_t r2;
    if (x <= 0) return 0;
    if (post == 0 && (e >= 62 || (uint64_t)x > ((((uint64_t)1 << 62) - ((uint64_t)1 << 31)) >> e)))
        return INT32_MAX;
    r2 = tx_isqrt(((uint64_t)x << e) << 2);
    return (int32_t)tx_rshr((int64_t)r2, 1 + post);
}

/* The int32_t whose two's complement is u. */
static inline int32_t tx_u2s32(uint32_t u) {
    return u >= ((uint32_t)1 << 31) ? -(int32_t)(~u) - 1 : (int32_t)u;
}

/* exp(x * 2^-fx) in format fr, as tactus_runtime::fixed::exp: k = round(x / ln2) from
   t = floor(x * 2^(8-fx)), r = x - k*ln2 in Q32 (a wrapping word), P = exp(r) in Q30 by
   Horner on the degree-8 Taylor polynomial, then P * 2^(k + fr - 30). xlo/xhi: the raw
   words beyond which k + fr <= -3 (result 0) or k + fr >= 32 (saturated), found by the
   compiler; between them |k| <= 64 and |t| < 2^14. */
static inline int32_t tx_exp(int32_t x, int fx, int fr, int32_t xlo, int32_t xhi) {
    static const int32_t c[9] = {1073741824, 1073741824, 536870912, 178956971, 44739243,
                                 8947849, 1491308, 213044, 26631};
    int32_t t, k, corr, r, p;
    uint32_t xq;
    int n;
    if (x > xhi) return INT32_MAX;
    if (x < xlo) return 0;
    t = (int32_t)(fx >= 8 ? tx_floor_shr(x, fx - 8) : (int64_t)x * ((int64_t)1 << (8 - fx)));
    k = (int32_t)tx_floor_shr((int64_t)t * 94548 + ((int64_t)1 << 23), 24);
    xq = fx > 32 ? (uint32_t)tx_floor_shr(x, fx - 32) : fx > 0 ? (uint32_t)x << (32 - fx) : 0u;
    corr = (int32_t)tx_floor_shr((int64_t)k * -3027078 + ((int64_t)1 << 23), 24);
    r = tx_u2s32(xq - (uint32_t)k * 0xB17217F8u - (uint32_t)corr);
    p = c[8];
    for (n = 7; n >= 0; n--) p = c[n] + (int32_t)tx_floor_shr((int64_t)p * r, 32);
    return tx_round(p, fr - 30 + k);
}
"#;

fn pow2(e: i32) -> String {
    format!("INT64_C({})", 1i64 << e)
}

/// `x · 2^e` rounded half up and saturated, `x` a C expression of type `int64_t`.
fn round_expr(x: &str, e: i32) -> String {
    if e == 0 {
        format!("tx_sat({x})")
    } else if e > 0 {
        format!("tx_shl_sat({x}, {e})")
    } else {
        format!("tx_sat(tx_rshr({x}, {}))", -e)
    }
}

/// [`fx::convert`]: the `int32_t` expression `x` from `from` to `to` fraction bits.
pub fn convert(x: &str, from: i32, to: i32) -> String {
    let e = to - from;
    if e == 0 {
        x.to_string()
    } else if e < 0 && -e >= 32 {
        // |x| < 2^31 <= 2^(m-1): the half-up rounding of x/2^m is 0.
        format!("((void)({x}), 0)")
    } else if e < 0 {
        format!("(int32_t)tx_rshr((int64_t)({x}), {})", -e)
    } else {
        round_expr(&format!("(int64_t)({x})"), e)
    }
}

/// [`fx::neg`]: `-x` from `fx` to `fr` fraction bits.
pub fn neg(x: &str, fx: i32, fr: i32) -> String {
    round_expr(&format!("-(int64_t)({x})"), fr - fx)
}

/// [`fx::add`] (`sub = false`) or [`fx::sub`]: `x ± y` into `fr` fraction bits.
pub fn add(x: &str, fx: i32, y: &str, fy: i32, fr: i32, sub: bool) -> String {
    let tx = (format!("(int64_t)({x})"), fr - fx);
    let ty = (
        if sub {
            format!("(-(int64_t)({y}))")
        } else {
            format!("(int64_t)({y})")
        },
        fr - fy,
    );
    // Exponents relative to the result's LSB; the coarse term has the larger one.
    let ((cx, e1), (cy, e2)) = if tx.1 >= ty.1 { (tx, ty) } else { (ty, tx) };
    let g = e2.max(e1.min(-1));
    let sy = (g - e2).min(63);
    let fine = if sy == 0 {
        cy
    } else {
        format!("tx_floor_shr({cy}, {sy})")
    };
    let dx = e1 - g;
    let coarse = if dx == 0 {
        cx
    } else if dx <= 31 {
        format!("{cx} * {}", pow2(dx))
    } else {
        format!("tx_clamp2({cx}) * {}", pow2(dx.min(40)))
    };
    round_expr(&format!("({coarse} + {fine})"), g)
}

/// [`fx::mul`] (`shifts = None`) or [`fx::mul_shifted`] with operand pre-shifts `(a, b)`:
/// `x · y` into `fr` fraction bits.
pub fn mul(x: &str, fx: i32, y: &str, fy: i32, fr: i32, shifts: Option<(u8, u8)>) -> String {
    match shifts {
        None => round_expr(&format!("((int64_t)({x}) * (int64_t)({y}))"), fr - fx - fy),
        Some((a, b)) => {
            // As the definition: the shift is capped at 31 but the exponent uses the planned
            // count (the planner never plans more than 31).
            let sh = |v: &str, s: u8| match s.min(31) {
                0 => format!("(int64_t)({v})"),
                s => format!("tx_floor_shr({v}, {s})"),
            };
            round_expr(
                &format!("({} * {})", sh(x, a), sh(y, b)),
                fr - (fx - a as i32) - (fy - b as i32),
            )
        }
    }
}

/// [`fx::mul_high`]: three 16×16 partial products of `x·y` in units of `2^k`, rounded to
/// `fr` (`tx_mul_high` computes the sum exactly in 64 bits).
///
/// [`fx::mul_high`]: tactus_runtime::fixed::mul_high
pub fn mul_high(x: &str, fx: i32, y: &str, fy: i32, k: u8, fr: i32) -> String {
    let k = k.clamp(16, 32);
    round_expr(
        &format!("tx_mul_high({x}, {y}, {k})"),
        fr - (fx + fy - k as i32),
    )
}

/// [`fx::mul_32x16`]: `x · (y >> b)` from two 16×16 partial products in units of `2^k`,
/// rounded to `fr` (`y` is the cut operand; `tx_mul_32x16` multiplies in 32 bits when the
/// cut word is a 16-bit half, as in every planned program, and sums exactly in 64 bits).
///
/// [`fx::mul_32x16`]: tactus_runtime::fixed::mul_32x16
pub fn mul_32x16(x: &str, fx: i32, y: &str, fy: i32, b: u8, k: u8, fr: i32) -> String {
    let (b, k) = (b.min(31), k.min(16));
    round_expr(
        &format!("tx_mul_32x16({x}, {y}, {b}, {k})"),
        fr - (fx + fy - b as i32 - k as i32),
    )
}

/// The derivative of a sensor: the exact raw difference `d` (an `int64_t` expression with
/// `|d| <= dmax`) times the gain word `k`, rounded to `e` more fraction bits (`e` may be
/// negative): `d·k·2^e`, as in the fixed interpreter.
pub fn deriv(d: &str, dmax: i64, k: i32, e: i32) -> String {
    if (dmax as i128) * (k as i128).abs() < (1i128 << 63) {
        round_expr(&format!("(({d}) * (int64_t){k})"), e)
    } else {
        format!("tx_round_wide({d}, {k}, {e})")
    }
}

/// [`fx::div_shifted`]: `x / (y >> b)` into `fr` fraction bits, truncated toward zero
/// (`b = 0`: [`fx::div`]).
///
/// [`fx::div_shifted`]: tactus_runtime::fixed::div_shifted
pub fn div(x: &str, fx: i32, y: &str, fy: i32, b: u8, fr: i32) -> String {
    let b = b.min(31);
    let k = (fr - fx + fy - b as i32).clamp(-94, 94);
    if b == 0 {
        format!("tx_div({x}, {y}, {k})")
    } else {
        format!("tx_div({x}, (int32_t)tx_floor_shr({y}, {b}), {k})")
    }
}

/// [`fx::sqrt`]: `sqrt(max(x, 0))` into `fr` fraction bits.
pub fn sqrt(x: &str, fx: i32, fr: i32) -> String {
    let mut e = 2 * fr - fx;
    let mut post = 0;
    if e < 0 {
        let p = (-e + 1) / 2;
        e += 2 * p;
        post = p;
    }
    // With a post shift, e is 0 or 1; without one, e >= 62 saturates every positive x.
    let e = e.min(62);
    let post = post.min(63);
    format!("tx_sqrt({x}, {e}, {post})")
}

/// The first raw word in `lo..=hi` where `pred` holds (`pred` monotone: false then true),
/// or `hi + 1`.
fn first_true(lo: i64, hi: i64, pred: impl Fn(i64) -> bool) -> i64 {
    let (mut a, mut b) = (lo, hi + 1);
    while a < b {
        let m = a + (b - a) / 2;
        if pred(m) {
            b = m;
        } else {
            a = m + 1;
        }
    }
    a
}

/// The raw words `(xlo, xhi)` of format `fx` outside which [`fx::exp`] into `fr` fraction
/// bits takes a shortcut: `x < xlo` gives 0 (`k + fr ≤ −3`), `x > xhi` saturates
/// (`k + fr ≥ 32`); `k` ([`fx::exp_k`]) is monotone in `x`, so they are found by bisection.
/// Between them `|k| ≤ 64`. `xlo` may be `i32::MAX + 1` and `xhi` `i32::MIN − 1` (empty).
pub fn exp_limits(fx: i32, fr: i32) -> (i64, i64) {
    let (lo, hi) = (i32::MIN as i64, i32::MAX as i64);
    let fr = fr as i64;
    let xhi = first_true(lo, hi, |w| fx::exp_k(w as i32, fx) + fr >= 32) - 1;
    let xlo = first_true(lo, hi, |w| fx::exp_k(w as i32, fx) + fr > -3);
    (xlo, xhi)
}

/// [`fx::exp`]: `exp(x)` into `fr` fraction bits.
pub fn exp(x: &str, fx: i32, fr: i32) -> String {
    let (xlo, xhi) = exp_limits(fx, fr);
    if xlo > i32::MAX as i64 {
        return format!("((void)({x}), 0)");
    }
    if xhi < i32::MIN as i64 {
        return format!("((void)({x}), INT32_MAX)");
    }
    let lit = |w: i64| {
        if w == i32::MIN as i64 {
            "INT32_MIN".to_string()
        } else {
            w.to_string()
        }
    };
    format!("tx_exp({x}, {fx}, {fr}, {}, {})", lit(xlo), lit(xhi))
}

fn c_op(op: CmpOp) -> &'static str {
    match op {
        CmpOp::Eq => "==",
        CmpOp::Ne => "!=",
        CmpOp::Lt => "<",
        CmpOp::Le => "<=",
        CmpOp::Gt => ">",
        CmpOp::Ge => ">=",
    }
}

/// [`fx::cmp`]: `x OP y` on exact values (an `int` expression, 0 or 1).
pub fn cmp(op: CmpOp, x: &str, fx: i32, y: &str, fy: i32) -> String {
    let o = c_op(op);
    let scaled = |v: &str, d: i32| {
        if d <= 31 {
            format!("(int64_t)({v}) * {}", pow2(d))
        } else {
            // |other| < 2^31 < 2^32: only the sign of v matters.
            format!("tx_clamp2({v}) * {}", pow2(32))
        }
    };
    if x == y && fx == fy {
        // A value compared with itself (`q != q`): the order is Equal; C compilers reject
        // the tautological comparison.
        let holds = matches!(op, CmpOp::Eq | CmpOp::Le | CmpOp::Ge);
        return format!("((void)({x}), {})", i32::from(holds));
    }
    match fx.cmp(&fy) {
        Ordering::Equal => format!("({x} {o} {y})"),
        Ordering::Greater => format!("((int64_t)({x}) {o} {})", scaled(y, fx - fy)),
        Ordering::Less => format!("({} {o} (int64_t)({y}))", scaled(x, fy - fx)),
    }
}

/// The thresholds of [`fx::cmp_const`] on the grid of `fx` fraction bits: `ge` is the first
/// raw word whose value is `>= c`, `gt` the first whose value is `> c` (each may be
/// `i32::MAX + 1` when no word qualifies): [`fx::cmp_const_thresholds`], the runtime's one
/// definition, which the JIT uses too.
pub fn thresholds(fx: i32, c: f64) -> (i64, i64) {
    fx::cmp_const_thresholds(fx, c)
}

/// [`fx::cmp_const`]: `x OP c` (or `c OP x` when `const_left`) on exact values, as integer
/// comparisons of the raw word with thresholds precomputed on its grid.
pub fn cmp_const(op: CmpOp, x: &str, fx: i32, c: f64, const_left: bool) -> String {
    let (lo, hi) = (i32::MIN as i64, i32::MAX as i64);
    let (ge, gt) = thresholds(fx, c);
    // Normalise `c OP x` to `x OP' c`.
    let op = if const_left { op.mirrored() } else { op };
    // `x >= t` / `x < t` as C, constant when t is outside the word range.
    let at_least = |t: i64, neg: bool| {
        if t <= lo || t > hi {
            (((t <= lo) != neg) as u8).to_string()
        } else if neg {
            format!("({x} < {t})")
        } else {
            format!("({x} >= {t})")
        }
    };
    let parts: Vec<String> = match op {
        CmpOp::Ge => vec![at_least(ge, false)],
        CmpOp::Lt => vec![at_least(ge, true)],
        CmpOp::Gt => vec![at_least(gt, false)],
        CmpOp::Le => vec![at_least(gt, true)],
        CmpOp::Eq | CmpOp::Ne => vec![at_least(ge, false), at_least(gt, true)],
    };
    let constant = parts.iter().any(|p| p.len() == 1);
    let mut expr = parts.join(" && ");
    if parts.len() > 1 {
        expr = format!("({expr})");
    }
    if op == CmpOp::Ne {
        expr = format!("!{expr}");
    }
    // Keep the operand evaluated (and used) even when the answer is a constant.
    if constant {
        format!("((void)({x}), {expr})")
    } else {
        expr
    }
}
