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
//! its operands ([`mul_shifted`]), and a comparison with a constant compares exact values
//! ([`cmp_const`]).
//!
//! Every engine (fixed interpreter, JIT, Thumb, C) must produce exactly these bits; the
//! functions here are the executable definition, computed in `i128` so that nothing is
//! lost before the single rounding.

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
    let scaled = (v * 2f64.powi(frac) + 0.5).floor();
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
    x as f64 * 2f64.powi(-frac)
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

/// `-x` in format `fr`.
pub fn neg(x: i32, fx: i32, fr: i32) -> Sat {
    sat32(rescale(-(x as i128), fx, fr))
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

/// Fraction bits of the internal exp computation.
const EXP_FRAC: i32 = 60;

/// `exp(x)` into format `fr`, by range reduction and a Taylor polynomial in Q60:
/// `x = k·ln2 + r` with `|r| ≤ ln2/2`, `exp(r)` from 16 Taylor terms (truncation error
/// < 2^-60), then `2^k`. Error bound: 2^-56 relative plus the final half-LSB rounding.
pub fn exp(x: i32, fx: i32, fr: i32) -> Sat {
    const LN2_Q60: i128 = 799_144_290_325_165_667; // round(ln 2 · 2^60)
    let xq = rescale(x as i128, fx, EXP_FRAC); // |x| < 2^31·2^-fx
                                               // k = round(x / ln2)
    let k = (2 * xq + LN2_Q60).div_euclid(2 * LN2_Q60);
    if k > 200 {
        return (i32::MAX, true);
    }
    if k < -200 {
        return (0, false);
    }
    let r = xq - k * LN2_Q60; // |r| <= ln2/2 in Q60
    let one = 1i128 << EXP_FRAC;
    let mut term = one;
    let mut sum = one;
    for n in 1..=16 {
        term = (term * r) >> EXP_FRAC;
        term /= n;
        sum += term;
    }
    // value = sum · 2^k · 2^-60 → format fr
    sat32(rescale(sum, EXP_FRAC - k as i32, fr))
}

#[cfg(test)]
mod tests {
    use super::*;

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
            let bound = 0.5 * 2f64.powi(-fr) + want * 2f64.powi(-50);
            assert!((got - want).abs() <= bound, "exp {v}: {got} vs {want}");
        }
    }
}
