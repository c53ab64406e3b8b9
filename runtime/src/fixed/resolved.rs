//! The fixed-point operations with their formats resolved once: shifts decided ahead, words
//! evaluated on `i64`.
//!
//! [`super`]'s functions take the formats as run-time arguments and compute in `i128`: each
//! call aligns, multiplies and rescales through 128-bit shifts and tests which way to shift.
//! They are the specification. An engine that runs one operation in one set of formats many
//! times (the fixed interpreter: every sample of a plan) splits it here into its
//! *resolution* — [`Align::new`], [`Product`]'s constructors, [`Threshold::new`], a shift
//! `sh` — made once, and its *evaluation* on words. Every intermediate fits an `i64`: a word
//! is below `2^31` in magnitude, a product of two words below `2^62`, a sum of two words
//! aligned by at most 31 bits below `2^62 + 2^31`; where an `i64` would not hold the exact
//! intermediate the resolution is `None` and the caller keeps the specification.
//!
//! Every form here has the rounding, saturation and overflow flag of its specification
//! function, named in its doc; the tests hold each to that function bit for bit over random
//! words and formats (overflow flag included). The products' partial sums (which partial
//! products [`super::mul_high`] and [`super::mul_32x16`] keep, and their floors) are not
//! spelled twice: both sides call the same private function of [`super`], so what the tests
//! hold here is the resolution of the shifts and the rounding.

use super::{cut_partial, high_partial, Sat};
use std::cmp::Ordering;

/// `x · 2^sh` rounded half up (a right shift when `sh < 0`) and saturated to `i32`, with the
/// overflow flag: [`super::rescale`] from any format `f` to `f + sh`, then [`super::sat32`],
/// for `|x| < 2^63 − 1`.
///
/// A left shift of a word that does not fit an `i32` saturates whatever the shift (so does
/// any nonzero word shifted by 32 bits or more); a right shift by `s` is
/// `((x >> (s − 1)) + 1) >> 1`, which is `floor((x + 2^(s−1)) / 2^s)` without the addition
/// that could leave the `i64` (and 0 for every `s > 63`, as `|x| < 2^63 ≤ 2^(s−1)`).
#[inline(always)]
pub fn round_shift(x: i64, sh: i32) -> Sat {
    let y = if sh >= 0 {
        if x == 0 {
            return (0, false);
        }
        if sh >= 32 || x > i64::from(i32::MAX) || x < i64::from(i32::MIN) {
            return if x > 0 {
                (i32::MAX, true)
            } else {
                (i32::MIN, true)
            };
        }
        x << sh
    } else {
        let s = (-i64::from(sh)).min(64) as u32;
        ((x >> (s - 1)) + 1) >> 1
    };
    sat64(y)
}

/// Saturates an `i64` to `i32`, with the overflow flag ([`super::sat32`]).
#[inline(always)]
fn sat64(y: i64) -> Sat {
    if y > i64::from(i32::MAX) {
        (i32::MAX, true)
    } else if y < i64::from(i32::MIN) {
        (i32::MIN, true)
    } else {
        (y as i32, false)
    }
}

/// [`super::convert`] of the word `x` from a format `f` to `f + sh`.
#[inline(always)]
pub fn convert(x: i32, sh: i32) -> Sat {
    round_shift(i64::from(x), sh)
}

/// [`super::neg`] of the word `x` from a format `f` to `f + sh`.
#[inline(always)]
pub fn neg(x: i32, sh: i32) -> Sat {
    round_shift(-i64::from(x), sh)
}

/// [`super::abs`] of the word `x` from a format `f` to `f + sh`.
#[inline(always)]
pub fn abs(x: i32, sh: i32) -> Sat {
    round_shift(i64::from(x).abs(), sh)
}

/// Two operands brought to the finer of their formats, as [`super::add`], [`super::sub`]
/// and [`super::cmp`] align them, and the shift from that format to the result's.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Align {
    /// Left shift of the first operand's word (at most 31).
    ax: u8,
    /// Left shift of the second operand's word (at most 31).
    ay: u8,
    /// Shift from the common format to the result's ([`round_shift`]).
    sh: i32,
}

impl Align {
    /// The alignment of words with `fx` and `fy` fraction bits into a result with `fr`;
    /// `None` when they are more than 31 bits apart (an aligned word would need more than
    /// 62 bits and a sum more than an `i64`).
    pub fn new(fx: i32, fy: i32, fr: i32) -> Option<Self> {
        let f = fx.max(fy);
        let (ax, ay) = (f - fx, f - fy);
        (ax <= 31 && ay <= 31).then_some(Align {
            ax: ax as u8,
            ay: ay as u8,
            sh: fr - f,
        })
    }

    /// Both words in the common format.
    #[inline(always)]
    fn words(self, x: i32, y: i32) -> (i64, i64) {
        (i64::from(x) << self.ax, i64::from(y) << self.ay)
    }

    /// [`super::add`]: the exact sum, rounded half up to the result's format, saturated.
    #[inline(always)]
    pub fn add(self, x: i32, y: i32) -> Sat {
        let (a, b) = self.words(x, y);
        round_shift(a + b, self.sh)
    }

    /// [`super::sub`]: the exact difference, rounded half up to the result's format,
    /// saturated.
    #[inline(always)]
    pub fn sub(self, x: i32, y: i32) -> Sat {
        let (a, b) = self.words(x, y);
        round_shift(a - b, self.sh)
    }

    /// [`super::cmp`]: the exact values' ordering (the result format plays no part).
    #[inline(always)]
    pub fn cmp(self, x: i32, y: i32) -> Ordering {
        let (a, b) = self.words(x, y);
        a.cmp(&b)
    }
}

/// A product in one of the runtime's forms, its shifts resolved (constructors below, one
/// per form, with their specification functions' clamps of the shift counts).
/// [`Product::eval`] takes the operand words in the order the specification function does.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Product(Form);

/// The forms, with the invariants their constructors establish.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Form {
    /// The exact product, then `sh`.
    Exact { sh: i32 },
    /// Each operand floored by its pre-shift (`a`, `b` ≤ 31), then `sh`.
    Shifted { a: u8, b: u8, sh: i32 },
    /// [`high_partial`] with `16 ≤ k ≤ 32`, then `sh`.
    High { k: u8, sh: i32 },
    /// [`cut_partial`] of the kept word and the cut word shifted by `b ≤ 31`, `k ≤ 16`,
    /// then `sh`.
    Cut { b: u8, k: u8, sh: i32 },
}

impl Product {
    /// [`super::mul`] of words with `fx` and `fy` fraction bits into `fr`: the exact product
    /// rounded once.
    pub fn exact(fx: i32, fy: i32, fr: i32) -> Self {
        Product(Form::Exact { sh: fr - (fx + fy) })
    }

    /// [`super::mul_shifted`]: the words floored by `a` and `b` bits (the shifts clamped to
    /// 31, the product's format `fx − a + fy − b` not), their exact product rounded once to
    /// `fr`.
    pub fn shifted(fx: i32, a: u8, fy: i32, b: u8, fr: i32) -> Self {
        Product(Form::Shifted {
            a: a.min(31),
            b: b.min(31),
            sh: fr - (fx - i32::from(a) + fy - i32::from(b)),
        })
    }

    /// [`super::mul_high`] with its unit `2^k` (`k` clamped to `16..=32`), rounded once to
    /// `fr`.
    pub fn high(fx: i32, fy: i32, k: u8, fr: i32) -> Self {
        let k = k.clamp(16, 32);
        Product(Form::High {
            k,
            sh: fr - (fx + fy - i32::from(k)),
        })
    }

    /// [`super::mul_32x16`] of a kept word with `fx` fraction bits and a cut word with `fy`,
    /// cut by `b` bits (at most 31), unit `2^k` (`k` at most 16), rounded once to `fr`.
    pub fn cut_32x16(fx: i32, fy: i32, b: u8, k: u8, fr: i32) -> Self {
        let (b, k) = (b.min(31), k.min(16));
        Product(Form::Cut {
            b,
            k,
            sh: fr - (fx + fy - i32::from(b) - i32::from(k)),
        })
    }

    /// The product of the words `x` and `y` (for [`Product::cut_32x16`]: `x` kept, `y` cut).
    #[inline(always)]
    pub fn eval(self, x: i32, y: i32) -> Sat {
        match self.0 {
            Form::Exact { sh } => round_shift(i64::from(x) * i64::from(y), sh),
            Form::Shifted { a, b, sh } => round_shift(i64::from(x >> a) * i64::from(y >> b), sh),
            Form::High { k, sh } => round_shift(high_partial(x, y, k), sh),
            Form::Cut { b, k, sh } => round_shift(cut_partial(x, y >> b, k), sh),
        }
    }
}

/// A comparison with a real constant as integer thresholds ([`super::cmp_const_thresholds`]):
/// the ordering of [`super::cmp_const`] for a word in the format resolved.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Threshold {
    /// The smallest word whose value is `≥ c` (`i32::MAX + 1` when none is).
    ge: i64,
    /// The smallest word whose value is `> c` (`i32::MAX + 1` when none is).
    gt: i64,
}

impl Threshold {
    /// The thresholds of the constant `c` for words with `fx` fraction bits (two bisections
    /// of 33 steps: resolve once, not per comparison).
    pub fn new(fx: i32, c: f64) -> Self {
        let (ge, gt) = super::cmp_const_thresholds(fx, c);
        Threshold { ge, gt }
    }

    /// [`super::cmp_const`] of the word `x`: its value's order against the constant.
    #[inline(always)]
    pub fn order(self, x: i32) -> Ordering {
        let x = i64::from(x);
        if x < self.ge {
            Ordering::Less
        } else if x < self.gt {
            Ordering::Equal
        } else {
            Ordering::Greater
        }
    }
}

#[cfg(test)]
mod tests {
    use super::super as fx;
    use super::*;
    use proptest::prelude::*;

    /// Words with every magnitude equally likely, and the extremes.
    fn word() -> impl Strategy<Value = i32> {
        prop_oneof![
            (0u32..32, any::<i32>()).prop_map(|(s, x)| x >> s),
            Just(i32::MIN),
            Just(i32::MAX),
            Just(0),
            Just(-1),
        ]
    }

    /// Fraction-bit counts across the formats' range and a little beyond.
    fn frac() -> impl Strategy<Value = i32> {
        fx::FRAC_RANGE.0 - 8..fx::FRAC_RANGE.1 + 8
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(20_000))]

        #[test]
        fn round_shift_is_rescale_then_sat32(
            x in prop_oneof![
                (0u32..63, any::<i64>()).prop_map(|(s, x)| x >> s),
                Just(i64::MAX - 1),
                Just(i64::MIN + 1),
            ],
            sh in -140i32..140,
        ) {
            prop_assert_eq!(round_shift(x, sh), fx::sat32(fx::rescale(x as i128, 7, 7 + sh)));
        }

        #[test]
        fn conversions_are_the_specification(x in word(), f in frac(), fr in frac()) {
            prop_assert_eq!(convert(x, fr - f), fx::convert(x, f, fr));
            prop_assert_eq!(neg(x, fr - f), fx::neg(x, f, fr));
            prop_assert_eq!(abs(x, fr - f), fx::abs(x, f, fr));
        }

        #[test]
        fn sums_and_comparisons_are_the_specification(
            x in word(), y in word(), fx_ in frac(), fy in frac(), fr in frac(),
        ) {
            match Align::new(fx_, fy, fr) {
                Some(al) => {
                    prop_assert_eq!(al.add(x, y), fx::add(x, fx_, y, fy, fr));
                    prop_assert_eq!(al.sub(x, y), fx::sub(x, fx_, y, fy, fr));
                    prop_assert_eq!(al.cmp(x, y), fx::cmp(x, fx_, y, fy));
                }
                None => prop_assert!((fx_ - fy).abs() > 31),
            }
        }

        /// Every form, its shift counts beyond their clamps included.
        #[test]
        fn products_are_the_specification(
            x in word(), y in word(), fx_ in frac(), fy in frac(), fr in frac(),
            a in 0u8..40, b in 0u8..40, k in 0u8..40,
        ) {
            prop_assert_eq!(Product::exact(fx_, fy, fr).eval(x, y), fx::mul(x, fx_, y, fy, fr));
            prop_assert_eq!(
                Product::shifted(fx_, a, fy, b, fr).eval(x, y),
                fx::mul_shifted(x, fx_, a, y, fy, b, fr)
            );
            prop_assert_eq!(
                Product::high(fx_, fy, k, fr).eval(x, y),
                fx::mul_high(x, fx_, y, fy, k, fr)
            );
            prop_assert_eq!(
                Product::cut_32x16(fx_, fy, b, k, fr).eval(x, y),
                fx::mul_32x16(x, fx_, y, fy, b, k, fr)
            );
        }

        #[test]
        fn thresholds_are_cmp_const(
            x in word(), fx_ in frac(),
            c in prop_oneof![
                any::<f64>(),
                (-1e6f64..1e6),
                Just(0.0), Just(-0.0), Just(f64::NAN), Just(f64::INFINITY),
                Just(f64::NEG_INFINITY),
            ],
        ) {
            prop_assert_eq!(Threshold::new(fx_, c).order(x), fx::cmp_const(x, fx_, c));
        }
    }

    /// A pre-shift beyond 31 bits clamps the shift, not the product's format (as
    /// [`fx::mul_shifted`] does): proptest's first find, kept as a case.
    #[test]
    fn a_preshift_beyond_31_bits_keeps_its_format() {
        assert_eq!(
            Product::shifted(0, 32, 0, 0, -12).eval(-1, -1),
            fx::mul_shifted(-1, 0, 32, -1, 0, 0, -12)
        );
        assert_eq!(
            Product::shifted(0, 32, 0, 0, -12).eval(-1, -1),
            (1 << 20, false)
        );
    }

    /// A threshold equal to a word's exact value, and its neighbours, on a fine and a
    /// coarse grid.
    #[test]
    fn thresholds_at_exact_words() {
        for f in [-20, 0, 17, 40] {
            for w in [-5, 0, 1, 123_456] {
                let c = fx::to_f64(w, f);
                let t = Threshold::new(f, c);
                for x in w - 2..=w + 2 {
                    assert_eq!(t.order(x), fx::cmp_const(x, f, c), "f {f} w {w} x {x}");
                }
            }
        }
    }

    /// The partial sums the products share with their specification, against the `i128`
    /// expressions the specification was written in before they were shared (so the sharing
    /// is checked, not assumed): every edge word and random ones, every unit `k`.
    #[test]
    fn partial_sums_are_exact_in_i64() {
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
        let mut rng = crate::rng::XorShift64::new(0x9a27);
        let mut words: Vec<i32> = edges.to_vec();
        words.extend((0..60).map(|n| (rng.next_u64() as i32) >> (n % 31)));
        for &x in &words {
            for &y in &words {
                let (xh, xl) = ((x >> 16) as i128, (x & 0xffff) as i128);
                let (yh, yl) = ((y >> 16) as i128, (y & 0xffff) as i128);
                for k in 16..=32u8 {
                    let s = u32::from(k);
                    let want =
                        ((xh * yh) << (32 - s)) + ((xh * yl) >> (s - 16)) + ((xl * yh) >> (s - 16));
                    assert_eq!(high_partial(x, y, k) as i128, want, "{x} {y} {k}");
                }
                for k in 0..=16u8 {
                    let want = ((xh * y as i128) << (16 - k)) + ((xl * y as i128) >> k);
                    assert_eq!(cut_partial(x, y, k) as i128, want, "{x} {y} {k}");
                }
            }
        }
    }
}
