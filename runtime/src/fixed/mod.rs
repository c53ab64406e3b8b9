//! The fixed-point primitives that define the bits of every engine.
//!
//! A run-time value is a 32-bit signed word `raw` with its own binary point: it stands for
//! `raw · 2^-frac`, where `frac` (the number of fraction bits, Q-format `Q(31-frac).frac`)
//! is chosen per value by the compiler's range analysis and may be negative or above 31.
//!
//! **The rule for every operation:** compute the exact result of the operation on the exact
//! values of the operands, round it once to the result's format — *round half up*,
//! `floor(v · 2^frac + 1/2)` — and saturate it to `[i32::MIN, i32::MAX]`. Saturation reports
//! an overflow flag, which the overflow-detecting interpreter records; where the range
//! analysis proved the result fits, it never fires. Exceptions, each defined below: division
//! truncates toward zero (what the RP2040's SIO divider computes), `sqrt` and `exp` are the
//! integer algorithms given here, a multiplication the compiler fits into `MULS` pre-shifts
//! its operands ([`mul_shifted`]), cuts one operand to 16 bits and keeps the other's 32
//! ([`mul_32x16`]) or keeps three of its four 16×16 partial products ([`mul_high`]), a
//! run-time division may pre-shift its divisor
//! ([`div_shifted`]), and a comparison with a constant compares exact values
//! ([`cmp_const`]).
//!
//! Every engine (fixed interpreter, JIT, Thumb, C) must produce exactly these bits; the
//! functions here are the executable definition, computed in `i128` so that nothing is
//! lost before the single rounding. They take the formats as run-time arguments; an engine
//! that runs one operation in one set of formats many times resolves its shifts once and
//! evaluates it on `i64` with [`resolved`], whose every form is held to its function here
//! bit for bit (overflow flag included) by that module's tests.

pub mod resolved;

/// Largest shift the primitives perform on an `i128` (larger shifts saturate or give 0).
const MAX_SHIFT: i32 = 94;

/// Lowest and highest fraction-bit counts a format may have.
pub const FRAC_RANGE: (i32, i32) = (-32, 62);

/// The finest format (fraction bits) whose signed 32-bit word holds every value of
/// magnitude up to `mag`: `30 − floor(log2(mag))`, so `|raw| < 2^31` (with a 1e-9 margin for
/// the rounding of `mag` itself). 30 for `mag = 0`; clamped to [`FRAC_RANGE`].
pub fn frac_for(mag: f64) -> i32 {
    let m = mag.abs() * (1.0 + 1e-9);
    if m == 0.0 {
        return 30;
    }
    if !m.is_finite() {
        return FRAC_RANGE.0;
    }
    (30 - m.log2().floor() as i32).clamp(FRAC_RANGE.0, FRAC_RANGE.1)
}

/// A raw word and whether producing it saturated.
pub type Sat = (i32, bool);

/// Saturates to `i32`, with the overflow flag.
pub fn sat32(x: i128) -> Sat {
    if x > i32::MAX as i128 {
        (i32::MAX, true)
    } else if x < i32::MIN as i128 {
        (i32::MIN, true)
    } else {
        (x as i32, false)
    }
}

/// `x · 2^-from` expressed with `to` fraction bits, rounded half up (exact when `to >= from`).
/// The result is an `i128`; a left shift that would leave the `i128` saturates to ±2^126
/// (which [`sat32`] then saturates to the `i32` bounds), a right shift rounds correctly.
pub fn rescale(x: i128, from: i32, to: i32) -> i128 {
    if to >= from {
        let s = to - from;
        if x == 0 {
            return 0;
        }
        // Saturate (far beyond any i32) instead of shifting bits out of the i128.
        let bits = 128 - x.unsigned_abs().leading_zeros() as i32;
        if s > MAX_SHIFT || s + bits >= 126 {
            return if x > 0 {
                i128::MAX >> 1
            } else {
                i128::MIN >> 1
            };
        }
        x << s
    } else {
        let s = from - to;
        if s > 126 {
            // |x| < 2^126 so x·2^-s + 1/2 lies in (0, 1): floor is 0.
            return 0;
        }
        (x + (1i128 << (s - 1))) >> s
    }
}

/// Converts a raw word between formats (rounded half up, saturated).
pub fn convert(x: i32, from: i32, to: i32) -> Sat {
    sat32(rescale(x as i128, from, to))
}

/// The raw word nearest to the real `v` in format `frac` (half up), saturated. NaN → 0.
pub fn from_f64(v: f64, frac: i32) -> Sat {
    if v.is_nan() {
        return (0, true);
    }
    let scaled = (v * pow2(frac) + 0.5).floor();
    if scaled >= 2147483647.0 {
        (i32::MAX, scaled > 2147483647.0)
    } else if scaled <= -2147483648.0 {
        (i32::MIN, scaled < -2147483648.0)
    } else {
        (scaled as i32, false)
    }
}

/// The real value of a raw word.
pub fn to_f64(x: i32, frac: i32) -> f64 {
    x as f64 * pow2(-frac)
}

/// `2^n`, exactly: built from its exponent bits for a normal `n` (−1022 to 1023), which is
/// what `2f64.powi(n)` gives there (a product of twos is exact) without its loop;
/// `powi` outside that range.
#[inline]
fn pow2(n: i32) -> f64 {
    if (-1022..=1023).contains(&n) {
        f64::from_bits(((n + 1023) as u64) << 52)
    } else {
        2f64.powi(n)
    }
}

/// Aligns two operands to their finer format: (x', y', frac).
fn align(x: i32, fx: i32, y: i32, fy: i32) -> (i128, i128, i32) {
    let f = fx.max(fy);
    (rescale(x as i128, fx, f), rescale(y as i128, fy, f), f)
}

/// `x + y` into format `fr`.
pub fn add(x: i32, fx: i32, y: i32, fy: i32, fr: i32) -> Sat {
    let (a, b, f) = align(x, fx, y, fy);
    sat32(rescale(a + b, f, fr))
}

/// `x - y` into format `fr`.
pub fn sub(x: i32, fx: i32, y: i32, fy: i32, fr: i32) -> Sat {
    let (a, b, f) = align(x, fx, y, fy);
    sat32(rescale(a - b, f, fr))
}

/// `x · y` into format `fr` (the exact 64-bit product, rounded once).
pub fn mul(x: i32, fx: i32, y: i32, fy: i32, fr: i32) -> Sat {
    sat32(rescale(x as i128 * y as i128, fx + fy, fr))
}

/// `x · y` with operand pre-shifts, as a 32×32→32 `MULS` computes it: `x >> a` and `y >> b`
/// (arithmetic shifts: floor), then their exact product rounded to `fr`. The compiler picks
/// `a`, `b` so that the shifted product fits 32 bits.
pub fn mul_shifted(x: i32, fx: i32, a: u8, y: i32, fy: i32, b: u8, fr: i32) -> Sat {
    let (xs, ys) = (x >> a.min(31), y >> b.min(31));
    sat32(rescale(
        xs as i128 * ys as i128,
        fx - a as i32 + fy - b as i32,
        fr,
    ))
}

/// `x / y` into format `fr`, truncated toward zero. `y = 0` saturates to the sign of `x`
/// (0 for `x = 0`) and reports an overflow.
pub fn div(x: i32, fx: i32, y: i32, fy: i32, fr: i32) -> Sat {
    if y == 0 {
        return (
            if x > 0 {
                i32::MAX
            } else if x < 0 {
                i32::MIN
            } else {
                0
            },
            true,
        );
    }
    // x/2^fx / (y/2^fy) · 2^fr = x · 2^(fr - fx + fy) / y
    let k = fr - fx + fy;
    let (n, d) = if k >= 0 {
        (rescale(x as i128, 0, k.min(MAX_SHIFT)), y as i128)
    } else {
        (x as i128, rescale(y as i128, 0, (-k).min(MAX_SHIFT)))
    };
    sat32(n / d)
}

/// The high part of `x · y` from three of the four 16×16 partial products, as a Cortex-M0+
/// computes it in 32-bit registers: with `x = xh·2^16 + xl` (`xh = x >> 16` signed,
/// `xl = x & 0xffff`) and likewise `y`,
/// `p = xh·yh·2^(32−k) + floor(xh·yl / 2^(k−16)) + floor(xl·yh / 2^(k−16))`, `16 ≤ k ≤ 32`:
/// `x·y / 2^k` without the low partial product `xl·yl` and with two floors, an error below
/// `2 + 2^(32−k)` units of `2^k` (so a few LSBs of 2^-62 relative for a full product). `p`
/// has `fx + fy − k` fraction bits and is rounded once to `fr` (half up, saturated). Every
/// partial product fits a signed 32-bit word (`|xh| ≤ 2^15`, `0 ≤ yl < 2^16`); the compiler
/// picks `k` so that `p` does too.
pub fn mul_high(x: i32, fx: i32, y: i32, fy: i32, k: u8, fr: i32) -> Sat {
    let k = k.clamp(16, 32);
    sat32(rescale(
        high_partial(x, y, k) as i128,
        fx + fy - k as i32,
        fr,
    ))
}

/// [`mul_high`]'s partial sum `p` (in units of `2^k`, `16 ≤ k ≤ 32`): the one definition of
/// which partial products it keeps and how it floors them, shared with [`resolved`]. Exact in
/// an `i64` for every pair of words: `|xh·yh| ≤ 2^30` shifted by at most 16 bits, each cross
/// term below `2^31`.
#[inline(always)]
fn high_partial(x: i32, y: i32, k: u8) -> i64 {
    let k = u32::from(k);
    let (xh, xl) = (i64::from(x >> 16), i64::from(x & 0xffff));
    let (yh, yl) = (i64::from(y >> 16), i64::from(y & 0xffff));
    ((xh * yh) << (32 - k)) + ((xh * yl) >> (k - 16)) + ((xl * yh) >> (k - 16))
}

/// `x · (y >> b)` from two 16×16 partial products, as a Cortex-M0+ computes a 32×16 product
/// in 32-bit registers: `y` is cut to `ys = y >> b` (arithmetic shift: floor; the compiler
/// picks `b` so that `ys` fits a signed 16-bit half, `−2^15 ≤ ys < 2^15`), `x` keeps its 32
/// bits as `x = xh·2^16 + xl` (`xh = x >> 16` signed, `xl = x & 0xffff`), and
/// `p = xh·ys·2^(16−k) + floor(xl·ys / 2^k)`, `0 ≤ k ≤ 16`: `x·ys / 2^k` with one floor.
/// `p` has `fx + fy − b − k` fraction bits and is rounded once to `fr` (half up, saturated).
///
/// Error before that rounding, in units of `2^(b + k − fx − fy)`: the floor loses
/// `0 ≤ δ < 1`; against the exact `x·y`, the cut adds `x·(ys·2^b − y) / 2^(b+k)`, with
/// `0 ≤ y − ys·2^b < 2^b` — below `|x| / 2^k` units, i.e. `|x|·2^(b − fy)` in SI, relative
/// at most `2^b / |y|` (≤ 2^-15 when `y` has its full 16 significant bits after the cut),
/// and nothing when the `b` dropped bits of `y` are zero (a constant's trailing zeros).
///
/// Which operand is cut: the one whose relative error matters less — for a product by a
/// constant the constant (its error is fixed and known at compile time), for two run-time
/// operands the side the compiler's error analysis picks. Callers pass the cut operand
/// as `y` (the product commutes).
///
/// Why both partial products fit a signed 32-bit word for *any* `x` when `ys` is a 16-bit
/// half: `|xh·ys| ≤ 2^15·2^15 = 2^30` and `|xl·ys| ≤ (2^16 − 1)·2^15 < 2^31` (`0 ≤ xl <
/// 2^16`); the compiler picks `k` so that the shifted high part and `p` fit too, and where
/// it can so that `p`'s format is `fr` (the floor then is the only rounding: an error of one
/// LSB of `fr`, far below the cut's). Two `MULS` instead of [`mul_high`]'s three, and one
/// half-split fewer. Computed here exactly for every word (`cut_partial`; also a `ys`
/// wider than 16 bits, which a planned program never has).
pub fn mul_32x16(x: i32, fx: i32, y: i32, fy: i32, b: u8, k: u8, fr: i32) -> Sat {
    let (b, k) = (b.min(31), k.min(16));
    sat32(rescale(
        cut_partial(x, y >> b, k) as i128,
        fx + fy - b as i32 - k as i32,
        fr,
    ))
}

/// [`mul_32x16`]'s partial sum `p = xh·ys·2^(16−k) + floor(xl·ys / 2^k)` of the kept word
/// `x` and the cut word `ys = y >> b` (`k ≤ 16`): the one definition of the form, shared with
/// [`resolved`]. Exact in an `i64` for every pair of words (also a `ys` wider than 16 bits):
/// `|xh·ys| ≤ 2^15·2^31` shifted by at most 16 bits is at most `2^62`, `|xl·ys| < 2^47`.
#[inline(always)]
fn cut_partial(x: i32, ys: i32, k: u8) -> i64 {
    let (ys, k) = (i64::from(ys), u32::from(k));
    let (xh, xl) = (i64::from(x >> 16), i64::from(x & 0xffff));
    ((xh * ys) << (16 - k)) + ((xl * ys) >> k)
}

/// `x / (y >> b)` into format `fr`: the divisor's word shifted right by `b` bits first
/// (arithmetic shift: floor; format `fy − b`), then [`div`] of the exact values — truncated
/// toward zero, saturated, a shifted divisor of 0 saturating as in [`div`]. `b = 0` is [`div`].
///
/// Why: a run-time division on a Cortex-M0+ is cheap on the RP2040's 32÷32 SIO divider only
/// when the divisor leaves room for quotient digits in a 32-bit dividend (a divisor of `L`
/// bits gives `32 − L` quotient bits per hardware division). The compiler picks `b` so that
/// the dropped divisor bits cost at most a stated relative error (`DIV_REL_TOLERANCE` in the
/// compiler's format plan); the quotient itself is exact for the shifted divisor.
pub fn div_shifted(x: i32, fx: i32, y: i32, fy: i32, b: u8, fr: i32) -> Sat {
    div(x, fx, y >> b.min(31), fy - b.min(31) as i32, fr)
}

/// Compares the exact values of two raw words.
pub fn cmp(x: i32, fx: i32, y: i32, fy: i32) -> std::cmp::Ordering {
    let (a, b, _) = align(x, fx, y, fy);
    a.cmp(&b)
}

/// Compares a raw word's exact value with a real constant, exactly. (A word's value is
/// exactly representable in an `f64`: 32 significant bits, exponent in range.) Comparisons
/// against constants are defined this way so that a threshold decides exactly as in the f64
/// semantics for every input on the word's grid; a backend implements `x >= c` as
/// `raw >= ceil(c·2^f)`, `x > c` as `raw > floor(c·2^f)`, and so on.
pub fn cmp_const(x: i32, fx: i32, c: f64) -> std::cmp::Ordering {
    to_f64(x, fx)
        .partial_cmp(&c)
        .unwrap_or(std::cmp::Ordering::Less)
}

/// The smallest raw word `w` (as an `i64`; `i32::MAX + 1` when there is none) for which
/// `pred(w)` holds, for a predicate that is false then true as `w` grows: a bisection over
/// all 2^32 words, 33 evaluations. How every backend turns a monotone definition into
/// compile-time thresholds ([`cmp_const_thresholds`], the shortcuts of [`exp`]).
pub fn first_word_where(pred: impl Fn(i32) -> bool) -> i64 {
    let (mut lo, mut hi) = (i32::MIN as i64, i32::MAX as i64 + 1);
    while lo < hi {
        let mid = lo + (hi - lo) / 2;
        // `mid <= i32::MAX` because `mid < hi`.
        if pred(mid as i32) {
            hi = mid;
        } else {
            lo = mid + 1;
        }
    }
    lo
}

/// The thresholds of [`cmp_const`] on the grid of format `fx`: `(ge, gt)`, the smallest raw
/// words whose exact value is `≥ c` resp. `> c` ([`first_word_where`]; `i32::MAX + 1` when
/// no word is). So `x ≥ c` is `raw ≥ ge`, `x > c` is `raw ≥ gt`, `x = c` is
/// `ge ≤ raw < gt`: how a backend compiles a comparison with a constant to integer compares.
/// One definition for the JIT, the C and the Thumb backends.
pub fn cmp_const_thresholds(fx: i32, c: f64) -> (i64, i64) {
    (
        first_word_where(|w| cmp_const(w, fx, c) != std::cmp::Ordering::Less),
        first_word_where(|w| cmp_const(w, fx, c) == std::cmp::Ordering::Greater),
    )
}

/// `-x` in format `fr`.
pub fn neg(x: i32, fx: i32, fr: i32) -> Sat {
    sat32(rescale(-(x as i128), fx, fr))
}

/// `|x|` in format `fr` ([`neg`] of a negative word, else [`convert`]).
pub fn abs(x: i32, fx: i32, fr: i32) -> Sat {
    sat32(rescale((x as i128).abs(), fx, fr))
}

/// `sqrt(max(x, 0))` into format `fr`: the exact square root, rounded half up.
pub fn sqrt(x: i32, fx: i32, fr: i32) -> Sat {
    if x <= 0 {
        return (0, false);
    }
    // sqrt(x·2^-fx)·2^fr = sqrt(x · 2^(2fr - fx)); make the exponent even first.
    let mut e = 2 * fr - fx;
    let mut n = x as i128;
    let mut post = 0; // extra right shift of the root
    if e < 0 {
        // sqrt(n·2^e) = sqrt(n·2^(e + 2p))·2^-p with e + 2p >= 0.
        let p = (-e + 1) / 2;
        e += 2 * p;
        post = p;
    }
    n = rescale(n, 0, e.min(MAX_SHIFT));
    if n >= 1i128 << 120 {
        // Only reachable with post = 0 (a positive post leaves n < 2^32): the root is at
        // least 2^60, far beyond an i32. Saturate, which also keeps `n << 2` in the i128.
        return (i32::MAX, true);
    }
    // Root with one extra bit, then round half up at the last step.
    let r2 = isqrt(n << 2); // floor(2·sqrt(n))
    let r = rescale(r2, 1 + post, 0);
    sat32(r)
}

/// floor(sqrt(n)) for n >= 0.
fn isqrt(n: i128) -> i128 {
    if n <= 0 {
        return 0;
    }
    let mut r = (n as f64).sqrt() as i128;
    while r * r > n {
        r -= 1;
    }
    while (r + 1) * (r + 1) <= n {
        r += 1;
    }
    r
}

/// `round(2^16 / ln 2)`: `exp`'s estimate of `x / ln 2`.
pub const EXP_INV_LN2_Q16: i32 = 94_548;
/// `round(ln 2 · 2^32)` (as an unsigned word: `0xB172_17F8`): `exp`'s `k·ln 2` modulo 2^32.
pub const EXP_LN2_Q32: u32 = 0xB172_17F8;
/// `round((ln 2 · 2^32 − EXP_LN2_Q32) · 2^24)`: the part of `ln 2 · 2^32` below
/// [`EXP_LN2_Q32`]'s last bit, in units of 2^-56.
pub const EXP_LN2_LO_Q56: i32 = -3_027_078;
/// `exp`'s Taylor coefficients `round(2^30 / n!)`, `n = 0..=8` (Q30).
pub const EXP_COEFFS_Q30: [i32; 9] = [
    1_073_741_824,
    1_073_741_824,
    536_870_912,
    178_956_971,
    44_739_243,
    8_947_849,
    1_491_308,
    213_044,
    26_631,
];
/// Bound of `exp`'s relative error before its final rounding: `|P·2^(k−30) − e^v| ≤
/// EXP_REL_ERR · e^v` (see [`exp`]).
pub const EXP_REL_ERR: f64 = 1.0 / (1u64 << 28) as f64;

/// `k = round(v / ln 2)` of `exp`'s range reduction for the raw word `x` in format `fx`
/// (`v = x·2^-fx`), to within 0.006: `t = floor(v·2^8)`, `k = floor((t·94548 + 2^23) / 2^24)`
/// ([`EXP_INV_LN2_Q16`]), clamped to `±2^40`. Monotone (non-decreasing) in `x`, so a backend finds the words where
/// `k` crosses a bound by bisection.
pub fn exp_k(x: i32, fx: i32) -> i64 {
    let t = if fx >= 8 {
        (x >> (fx - 8).min(31)) as i128
    } else {
        (x as i128) << (8 - fx)
    };
    // Clamped far beyond where the result saturates or is 0 (|k| ≤ 2^40 keeps it an i64).
    ((t * EXP_INV_LN2_Q16 as i128 + (1 << 23)) >> 24).clamp(-(1 << 40), 1 << 40) as i64
}

/// `floor(a · b / 2^32)`, the high word of the signed 64-bit product (one step of `exp`'s
/// polynomial).
pub fn mulhi(a: i32, b: i32) -> i32 {
    ((a as i64 * b as i64) >> 32) as i32
}

/// `exp(x)` into format `fr`: a fixed-point algorithm of 32-bit words, cheap on a Cortex-M0+
/// (one `MULS` for the reduction, eight 32×32→64 products for the polynomial), the same bits
/// on every engine. With `v = x·2^-fx`:
///
/// 1. `k = round(v / ln 2)` to within 0.006 ([`exp_k`]). If `k + fr ≥ 32` the result
///    saturates (`(i32::MAX, true)`); if `k + fr ≤ −3` it is 0 — both are what step 4 gives,
///    so these are shortcuts, and they bound `|k| ≤ 64`, `|v| < 45` for steps 2–4.
/// 2. `r = v − k·ln 2` in Q32, as a wrapping 32-bit word: `X − k·L − round(k·D / 2^24)` where
///    `X = x·2^(32−fx) mod 2^32` (for `fx > 32`: `floor(x / 2^(fx−32))`),
///    `L` = [`EXP_LN2_Q32`], `D` = [`EXP_LN2_LO_Q56`]. Then `|r| ≤ 0.3515·2^32`, within 1.5
///    units of the exact `(v − k·ln 2)·2^32`.
/// 3. `P = exp(r·2^-32)` in Q30 by Horner's rule on the degree-8 Taylor polynomial
///    (coefficients [`EXP_COEFFS_Q30`]): `p = c8`, then `p = c_n + floor(p·r / 2^32)`
///    ([`mulhi`]) for `n = 7, …, 0`.
/// 4. The result is `P·2^(k + fr − 30)` rounded half up and saturated ([`rescale`]).
///
/// Error bound (relative, before the final rounding): the Horner floors and coefficient
/// roundings add at most 1.58 LSB of Q30 (each step's error is damped by `|r| ≤ 0.3515` in
/// the following steps), the Taylor remainder `|r|^9/9!·e^|r|` at most 0.35 LSB, the error of
/// `r` at most 1.5·2^-32·e^|r| = 0.54 LSB; 2.47 LSB against `P ≥ e^-0.3515·2^30` is below
/// 3.6·2^-30 < [`EXP_REL_ERR`] = 2^-28. So `|result − e^v·2^fr| ≤ 2^-28·e^v·2^fr + 1/2`
/// (in LSBs of `fr`), unless it saturates. Method: Cody–Waite style range reduction with a
/// two-part `ln 2` and a truncated Taylor series (J.-M. Muller, *Elementary Functions*, 3rd
/// ed., 2016, ch. 11); coefficients `round(2^30/n!)`.
pub fn exp(x: i32, fx: i32, fr: i32) -> Sat {
    let k = exp_k(x, fx);
    if k + fr as i64 >= 32 {
        return (i32::MAX, true);
    }
    if k + (fr as i64) <= -3 {
        return (0, false);
    }
    let k = k as i32; // |k| <= 64
    let big_x = if fx > 32 {
        x >> (fx - 32)
    } else if fx > 0 {
        ((x as u32) << (32 - fx)) as i32
    } else {
        0
    };
    let corr = (k * EXP_LN2_LO_Q56 + (1 << 23)) >> 24;
    let r = big_x
        .wrapping_sub(k.wrapping_mul(EXP_LN2_Q32 as i32))
        .wrapping_sub(corr);
    let mut p = EXP_COEFFS_Q30[8];
    for n in (0..8).rev() {
        p = EXP_COEFFS_Q30[n] + mulhi(p, r);
    }
    sat32(rescale(p as i128, 30 - k, fr))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn pow2_is_powi_of_two() {
        for n in -1100..=1100 {
            assert_eq!(pow2(n).to_bits(), 2f64.powi(n).to_bits(), "2^{n}");
        }
    }

    fn val(s: Sat, f: i32) -> f64 {
        assert!(!s.1, "overflow");
        to_f64(s.0, f)
    }

    #[test]
    fn rounding_is_half_up() {
        assert_eq!(rescale(3, 1, 0), 2); // 1.5 → 2
        assert_eq!(rescale(-3, 1, 0), -1); // -1.5 → -1
        assert_eq!(rescale(5, 2, 0), 1); // 1.25 → 1
        assert_eq!(from_f64(0.75, 1), (2, false));
        assert_eq!(from_f64(-0.75, 1), (-1, false));
    }

    #[test]
    fn huge_left_shifts_saturate_by_sign() {
        assert_eq!(sat32(rescale(1 << 62, 0, 80)), (i32::MAX, true));
        assert_eq!(sat32(rescale(-(1 << 62), 0, 80)), (i32::MIN, true));
        assert_eq!(exp(from_f64(105.0, 24).0, 24, 0), (i32::MAX, true));
    }

    #[test]
    fn ops_are_exact_then_rounded() {
        let (a, fa) = (from_f64(1.25, 20).0, 20);
        let (b, fb) = (from_f64(-0.3, 28).0, 28);
        let exact = to_f64(a, fa) * to_f64(b, fb);
        assert!((val(mul(a, fa, b, fb, 29), 29) - exact).abs() <= 2f64.powi(-30));
        let s = to_f64(a, fa) + to_f64(b, fb);
        assert!((val(add(a, fa, b, fb, 29), 29) - s).abs() <= 2f64.powi(-30));
        assert_eq!(add(i32::MAX, 0, 1, 0, 0), (i32::MAX, true));
        let q = to_f64(a, fa) / to_f64(b, fb);
        assert!((val(div(a, fa, b, fb, 26), 26) - q).abs() <= 2f64.powi(-26));
        assert_eq!(div(5, 0, 0, 0, 0), (i32::MAX, true));
    }

    /// The thresholds decide every word as `cmp_const` does (checked around them).
    #[test]
    fn cmp_const_thresholds_split_the_grid() {
        for &(fx, c) in &[
            (20, 0.3),
            (37, 0.0094),
            (-3, 1e12),
            (30, -1.5),
            (10, f64::NAN),
            (5, 1e-30),
        ] {
            let (ge, gt) = cmp_const_thresholds(fx, c);
            for w in [ge - 2, ge - 1, ge, ge + 1, gt - 1, gt, gt + 1] {
                if w < i32::MIN as i64 || w > i32::MAX as i64 {
                    continue;
                }
                let o = cmp_const(w as i32, fx, c);
                assert_eq!(o != std::cmp::Ordering::Less, w >= ge, "{fx} {c} {w}");
                assert_eq!(o == std::cmp::Ordering::Greater, w >= gt, "{fx} {c} {w}");
            }
        }
    }

    /// `mul_high` is within `2 + 2^(32−k)` units of `2^k` of the exact product before its
    /// rounding.
    #[test]
    fn mul_high_is_the_product_without_its_low_partial() {
        let mut rng = crate::rng::XorShift64::new(0x41);
        for n in 0..50_000u32 {
            let x = (rng.next_u64() as i32) >> (n % 5);
            let y = (rng.next_u64() as i32) >> (n % 7);
            let k = 16 + (n % 17) as u8;
            // p in its own format (fr = fx + fy − k): no final rounding.
            let (p, sat) = mul_high(x, 0, y, 0, k, -(k as i32));
            let exact = x as f64 * y as f64 / 2f64.powi(k as i32);
            if sat {
                assert!(exact.abs() > 2.0e9, "{x} {y} {k}");
                continue;
            }
            let bound = 2.0 + 2f64.powi(32 - k as i32);
            assert!(
                (p as f64 - exact).abs() <= bound,
                "{x} {y} {k}: {p} vs {exact}"
            );
        }
        assert_eq!(mul_high(1 << 20, 10, 3 << 20, 10, 32, 0), (3 << 20, false));
    }

    /// `mul_32x16` is `x·(y >> b)` within one unit of `2^k` below the exact product before
    /// its rounding (one floor); against `x·y` it is within `|x|·2^b` more; it equals `mul`
    /// when `y`'s dropped bits are zero and `k = 0`; edge words included.
    #[test]
    fn mul_32x16_is_the_product_by_the_cut_operand_with_one_floor() {
        let mut rng = crate::rng::XorShift64::new(0x3216);
        let edges = [
            i32::MIN,
            i32::MIN + 1,
            -65536,
            -65535,
            -1,
            0,
            1,
            0xffff,
            0x10000,
            i32::MAX,
        ];
        let mut cases: Vec<(i32, i32, u8, u8)> = Vec::new();
        for &x in &edges {
            for &ys in &[-32768i32, -32767, -1, 0, 1, 32767] {
                for (b, k) in [(0u8, 16u8), (16, 16), (15, 0), (3, 7)] {
                    cases.push((x, ys.wrapping_shl(b as u32) | ((1 << b) - 1), b, k));
                }
            }
        }
        for n in 0..50_000u32 {
            let b = (n % 17) as u8;
            let y = ((rng.next_u64() as i32) >> 16) << b | (rng.next_u64() as i32 & ((1 << b) - 1));
            cases.push(((rng.next_u64() as i32) >> (n % 5), y, b, (n % 17) as u8));
        }
        for (x, y, b, k) in cases {
            let ys = (y >> b) as i64;
            assert!((-32768..32768).contains(&ys), "{y} >> {b}");
            // p in its own format (fr = fx + fy − b − k): no final rounding.
            let (p, sat) = mul_32x16(x, 0, y, 0, b, k, -(b as i32) - (k as i32));
            let exact_cut = x as i128 * ys as i128; // units of 2^b
            if sat {
                assert!((exact_cut >> k).abs() >= 1 << 31, "{x} {y} {b} {k}");
                continue;
            }
            // One floor: exact_cut/2^k − 1 < p ≤ exact_cut/2^k.
            let scaled = (p as i128) << k;
            assert!(
                scaled <= exact_cut && exact_cut < scaled + (1 << k),
                "{x} {y} {b} {k}: {p}"
            );
            // Against the uncut product: within |x|·2^b + 2^(b+k).
            let err = (((p as i128) << (b + k)) - x as i128 * y as i128).abs();
            assert!(
                err <= (x as i128).abs() * (1 << b) + (1i128 << (b + k)),
                "{x} {y} {b} {k}"
            );
        }
        // Exact when nothing is dropped: y's low bits zero and k = 0 (in range).
        assert_eq!(
            mul_32x16(123_456, 10, 3 << 12, 20, 12, 0, 12),
            mul(123_456, 10, 3 << 12, 20, 12)
        );
        assert_eq!(
            mul_32x16(-7 << 20, 3, -5 << 8, 1, 8, 0, -2),
            mul(-7 << 20, 3, -5 << 8, 1, -2)
        );
        // Rounded once to fr (half up) from p's format.
        let (p, _) = mul_32x16(3, 0, 1, 0, 0, 1, -1); // 3·1/2 = 1.5 units of 2: p = 1
        assert_eq!(p, 1);
        assert_eq!(mul_32x16(3, 0, 1, 0, 0, 0, -1), (2, false)); // 3/2 = 1.5 → 2
    }

    /// `div_shifted` is `div` by the floor-shifted divisor: exact for that divisor, and
    /// within `2^b / |y|` relative error of the unshifted quotient.
    #[test]
    fn div_shifted_divides_by_the_shifted_divisor() {
        assert_eq!(div_shifted(1000, 0, 7, 0, 0, 0), div(1000, 0, 7, 0, 0));
        // 7 >> 1 = 3 with one fraction bit less: 1000 / 6 = 166 (truncated).
        assert_eq!(div_shifted(1000, 0, 7, 0, 1, 0), (166, false));
        // Negative divisors floor: -7 >> 1 = -4, i.e. -8 → 1000 / -8 = -125.
        assert_eq!(div_shifted(1000, 0, -7, 0, 1, 0), (-125, false));
        // A divisor shifted to 0 saturates like a division by 0.
        assert_eq!(div_shifted(5, 0, 3, 0, 2, 0), (i32::MAX, true));
        let mut rng = crate::rng::XorShift64::new(0xD1F);
        for _ in 0..20_000 {
            let x = (rng.next_u64() as i32) >> (rng.next_u64() % 20);
            let y = ((rng.next_u64() as i32) >> (rng.next_u64() % 8)) | (1 << 22);
            let b = (rng.next_u64() % 8) as u8;
            let (q, sat) = div_shifted(x, 20, y, 28, b, 30);
            if sat {
                continue;
            }
            let exact = to_f64(x, 20) / to_f64(y, 28);
            let err = (to_f64(q, 30) - exact).abs();
            let bound = exact.abs() * 2f64.powi(b as i32)
                / (y.unsigned_abs() as f64 - 2f64.powi(b as i32))
                + 2f64.powi(-30);
            assert!(err <= bound * (1.0 + 1e-12), "{x} {y} {b}: {err} > {bound}");
        }
    }

    #[test]
    fn sqrt_and_exp_are_within_their_bounds() {
        for &(v, fx, fr) in &[
            (2.0, 20, 28),
            (1e-6, 40, 40),
            (12345.0, 10, 20),
            (0.5, 30, 30),
        ] {
            let x = from_f64(v, fx).0;
            let got = val(sqrt(x, fx, fr), fr);
            let want = to_f64(x, fx).sqrt();
            assert!(
                (got - want).abs() <= 0.5 * 2f64.powi(-fr) * (1.0 + 1e-9),
                "sqrt {v}: {got} {want}"
            );
        }
        for &(v, fx, fr) in &[
            (0.0, 28, 29),
            (1.0, 28, 28),
            (-3.7, 26, 34),
            (10.0, 26, 15),
            (-20.0, 24, 45),
        ] {
            let x = from_f64(v, fx).0;
            let got = val(exp(x, fx, fr), fr);
            let want = to_f64(x, fx).exp();
            let bound = 0.5 * 2f64.powi(-fr) + want * EXP_REL_ERR;
            assert!((got - want).abs() <= bound, "exp {v}: {got} vs {want}");
        }
    }

    /// `exp` against `f64::exp` on random words of many formats: within its documented bound
    /// wherever it does not saturate, saturated only where the exact value is at least
    /// `2^31·(1 − 2^-28)` LSBs, and the shortcuts of step 1 agree with step 4.
    #[test]
    fn exp_meets_its_error_bound_on_random_words() {
        let mut rng = crate::rng::XorShift64::new(0xE4B);
        let mut worst = 0f64;
        for n in 0..400_000i32 {
            let fx = -32 + n % 95;
            let fr = -32 + (n / 95) % 95;
            // Words whose values are near the interesting range |v| < 50.
            let v = (rng.unit() * 2.0 - 1.0) * 50.0;
            let x = if n % 7 == 0 {
                rng.next_u64() as i32
            } else {
                from_f64(v, fx).0
            };
            let (got, sat) = exp(x, fx, fr);
            let want = (to_f64(x, fx)).exp() * 2f64.powi(fr);
            if sat {
                assert_eq!(got, i32::MAX);
                assert!(want >= 2147483648.0 * (1.0 - EXP_REL_ERR), "{x} {fx} {fr}");
                continue;
            }
            let err = (got as f64 - want).abs();
            assert!(
                err <= 0.5 + want * EXP_REL_ERR,
                "exp({x}, {fx}, {fr}) = {got}, exact {want}"
            );
            if want > 1e6 {
                worst = worst.max((err - 0.5).max(0.0) / want);
            }
            // The shortcuts: step 4 with the bounded k gives the same word.
            let k = exp_k(x, fx);
            if (-3 - fr as i64..=31 - fr as i64).contains(&k) {
                assert!(got >= 0);
            }
        }
        println!("worst relative error beyond the half LSB: {worst:.3e} (bound {EXP_REL_ERR:.3e})");
        assert!(worst <= EXP_REL_ERR, "{worst}");
    }

    /// Step 1's shortcuts of `exp` are what step 4 gives at the edge: at `k + fr = 31` a
    /// result may still fit, at `k + fr = −2` it may still round to 1.
    #[test]
    fn exp_shortcuts_are_step_four_at_their_edges() {
        // v just below 31·ln 2 (k = 31), fr = 0: about 2^31·e^-0.35, not saturated.
        let fx = 20;
        let x = from_f64(30.6 * std::f64::consts::LN_2, fx).0;
        assert_eq!(exp_k(x, fx), 31);
        assert!(!exp(x, fx, 0).1);
        // At v = -2·ln2 + 0.3 with fr = 0: k = −2 but the value 0.34 LSB rounds to 0; with
        // fr = 1 it is 0.68 → 1.
        let x = from_f64(-2.0 * std::f64::consts::LN_2 + 0.3, fx).0;
        assert_eq!(exp_k(x, fx), -2);
        assert_eq!(exp(x, fx, 0), (0, false));
        assert_eq!(exp(x, fx, 1), (1, false));
    }
}
