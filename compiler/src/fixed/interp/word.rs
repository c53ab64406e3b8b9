//! The fixed interpreter's hot operations on `i64`, with their shifts resolved once per plan.
//!
//! [`tactus_runtime::fixed`] defines every operation in `i128` with the formats as run-time
//! arguments: each call aligns, multiplies and rescales through 128-bit shifts and tests which
//! way to shift. For the operations a body runs every sample (sums, products in each planned
//! form, comparisons, conversions) the formats are known when the plan is, and every
//! intermediate fits an `i64`: a word is below 2^31 in magnitude, a product of two words
//! below 2^62, a sum of two words aligned by at most 31 bits below 2^62 + 2^31. Here each
//! operation is split into its resolution ([`Align::new`], [`Product::new`]: the shifts, or
//! `None` where an `i64` would not hold the exact intermediate and the caller keeps the
//! runtime's definition) and its evaluation on words. The tests hold every evaluation to the
//! runtime's function bit for bit, overflow flag included, over random words and formats.

use crate::fixed::{Cut, MulKind};
use tactus_runtime::fixed as fx;

/// `x · 2^sh` rounded half up (a right shift when `sh < 0`) and saturated to `i32`, with the
/// overflow flag: `fx::sat32(fx::rescale(x, from, from + sh))` for `|x| < 2^63 − 1`.
///
/// A left shift of a word that does not fit an `i32` saturates whatever the shift (so does
/// any nonzero word shifted by 32 bits or more); a right shift by `s` is
/// `((x >> (s − 1)) + 1) >> 1`, which is `floor((x + 2^(s−1)) / 2^s)` without the addition
/// that could leave the `i64` (and 0 for every `s > 63`, as `|x| < 2^63 ≤ 2^(s−1)`).
#[inline(always)]
pub(super) fn round_shift(x: i64, sh: i32) -> fx::Sat {
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

/// Saturates an `i64` to `i32`, with the overflow flag ([`fx::sat32`]).
#[inline(always)]
fn sat64(y: i64) -> fx::Sat {
    if y > i64::from(i32::MAX) {
        (i32::MAX, true)
    } else if y < i64::from(i32::MIN) {
        (i32::MIN, true)
    } else {
        (y as i32, false)
    }
}

/// Two operands brought to the finer of their formats, as [`fx::add`], [`fx::sub`] and
/// [`fx::cmp`] align them, and the shift from that format to the result's.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) struct Align {
    /// Left shift of the first operand's word.
    ax: u8,
    /// Left shift of the second operand's word.
    ay: u8,
    /// Shift from the common format to the result's ([`round_shift`]).
    sh: i32,
}

impl Align {
    /// The alignment of words with `fx` and `fy` fraction bits into a result with `fr`;
    /// `None` when they are more than 31 bits apart (an aligned word would need more than
    /// 62 bits and a sum more than an `i64`).
    pub(super) fn new(fx: i32, fy: i32, fr: i32) -> Option<Self> {
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

    /// [`fx::add`].
    #[inline(always)]
    pub(super) fn add(self, x: i32, y: i32) -> fx::Sat {
        let (a, b) = self.words(x, y);
        round_shift(a + b, self.sh)
    }

    /// [`fx::sub`].
    #[inline(always)]
    pub(super) fn sub(self, x: i32, y: i32) -> fx::Sat {
        let (a, b) = self.words(x, y);
        round_shift(a - b, self.sh)
    }

    /// [`fx::cmp`] (the result format plays no part).
    #[inline(always)]
    pub(super) fn cmp(self, x: i32, y: i32) -> std::cmp::Ordering {
        let (a, b) = self.words(x, y);
        a.cmp(&b)
    }
}

/// A product in the form its plan chose, its shifts resolved: the evaluation of
/// `super::product` (each form's runtime function) on the operand words in operand order.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) enum Product {
    /// [`fx::mul`]: the exact product, then `sh`.
    Exact {
        /// Shift from `fx + fy` to the result's format.
        sh: i32,
    },
    /// [`fx::mul_shifted`]: each operand floored by its pre-shift (at most 31), then `sh`.
    Shifted {
        /// First operand's pre-shift.
        a: u8,
        /// Second operand's pre-shift.
        b: u8,
        /// Shift from the product's format to the result's.
        sh: i32,
    },
    /// [`fx::mul_high`] with `16 ≤ k ≤ 32`, then `sh`.
    High {
        /// The partial sum's unit `2^k`.
        k: u8,
        /// Shift from `fx + fy − k` to the result's format.
        sh: i32,
    },
    /// [`fx::mul_32x16`] with `b ≤ 31`, `k ≤ 16`, then `sh`; `swap` when the cut operand
    /// is the first (the runtime function takes it second).
    Cut {
        /// Whether the operands trade places ([`Cut::kept_cut`]).
        swap: bool,
        /// The cut operand's pre-shift.
        b: u8,
        /// The partial sum's unit `2^k`.
        k: u8,
        /// Shift from the partial sum's format to the result's.
        sh: i32,
    },
}

impl Product {
    /// The product of words with `fx` and `fy` fraction bits into `fr` fraction bits in the
    /// form `kind` (`None`: the exact product), with the runtime functions' clamps of the
    /// shift counts.
    pub(super) fn new(kind: Option<MulKind>, fx: i32, fy: i32, fr: i32) -> Self {
        match kind {
            Some(MulKind::Muls(a, b)) => Product::Shifted {
                a: a.min(31),
                b: b.min(31),
                sh: fr - (fx - i32::from(a) + fy - i32::from(b)),
            },
            Some(MulKind::High(k)) => {
                let k = k.clamp(16, 32);
                Product::High {
                    k,
                    sh: fr - (fx + fy - i32::from(k)),
                }
            }
            Some(MulKind::Mul32x16 { cut, b, k }) => {
                let ((_, fa), (_, fc)) = cut.kept_cut((0, fx), (0, fy));
                let (b, k) = (b.min(31), k.min(16));
                Product::Cut {
                    swap: cut == Cut::First,
                    b,
                    k,
                    sh: fr - (fa + fc - i32::from(b) - i32::from(k)),
                }
            }
            _ => Product::Exact { sh: fr - (fx + fy) },
        }
    }

    /// The product of the words `x` and `y` (operand order).
    #[inline(always)]
    pub(super) fn eval(self, x: i32, y: i32) -> fx::Sat {
        match self {
            Product::Exact { sh } => round_shift(i64::from(x) * i64::from(y), sh),
            Product::Shifted { a, b, sh } => round_shift(i64::from(x >> a) * i64::from(y >> b), sh),
            Product::High { k, sh } => {
                // |xh·yh| ≤ 2^30, shifted by at most 16; the cross terms below 2^31.
                let (xh, xl) = (i64::from(x >> 16), i64::from(x & 0xffff));
                let (yh, yl) = (i64::from(y >> 16), i64::from(y & 0xffff));
                let k = u32::from(k);
                let p = ((xh * yh) << (32 - k)) + ((xh * yl) >> (k - 16)) + ((xl * yh) >> (k - 16));
                round_shift(p, sh)
            }
            Product::Cut { swap, b, k, sh } => {
                let (x, y) = if swap { (y, x) } else { (x, y) };
                // |xh·ys| ≤ 2^15·2^31 shifted by at most 16, |xl·ys| < 2^47: below 2^63.
                let ys = i64::from(y >> b);
                let (xh, xl) = (i64::from(x >> 16), i64::from(x & 0xffff));
                let p = ((xh * ys) << (16 - k)) + ((xl * ys) >> k);
                round_shift(p, sh)
            }
        }
    }
}

/// A comparison with a real constant as integer thresholds ([`fx::cmp_const_thresholds`]):
/// the ordering of [`fx::cmp_const`] for a word in the format resolved.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) struct Threshold {
    /// The smallest word whose value is `≥ c`.
    ge: i64,
    /// The smallest word whose value is `> c`.
    gt: i64,
}

impl Threshold {
    /// The thresholds of the constant `c` for words with `fx` fraction bits.
    pub(super) fn new(fx: i32, c: f64) -> Self {
        let (ge, gt) = fx::cmp_const_thresholds(fx, c);
        Threshold { ge, gt }
    }

    /// [`fx::cmp_const`] of the word `x`.
    #[inline(always)]
    pub(super) fn cmp(self, x: i32) -> std::cmp::Ordering {
        let x = i64::from(x);
        if x < self.ge {
            std::cmp::Ordering::Less
        } else if x < self.gt {
            std::cmp::Ordering::Equal
        } else {
            std::cmp::Ordering::Greater
        }
    }
}

#[cfg(test)]
mod tests {
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

    fn kind() -> impl Strategy<Value = Option<MulKind>> {
        prop_oneof![
            Just(None),
            Just(Some(MulKind::Wide)),
            (0u8..40, 0u8..40).prop_map(|(a, b)| Some(MulKind::Muls(a, b))),
            (0u8..40).prop_map(|k| Some(MulKind::High(k))),
            (any::<bool>(), 0u8..40, 0u8..20).prop_map(|(first, b, k)| {
                let cut = if first { Cut::First } else { Cut::Second };
                Some(MulKind::Mul32x16 { cut, b, k })
            }),
        ]
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
        fn sums_and_comparisons_are_the_runtimes(
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

        #[test]
        fn products_are_the_runtimes(
            x in word(), y in word(), fx_ in frac(), fy in frac(), fr in frac(), kind in kind(),
        ) {
            let want = match kind {
                Some(MulKind::Muls(a, b)) => fx::mul_shifted(x, fx_, a, y, fy, b, fr),
                Some(MulKind::High(k)) => fx::mul_high(x, fx_, y, fy, k, fr),
                Some(MulKind::Mul32x16 { cut, b, k }) => {
                    let ((a, fa), (c, fc)) = cut.kept_cut((x, fx_), (y, fy));
                    fx::mul_32x16(a, fa, c, fc, b, k, fr)
                }
                _ => fx::mul(x, fx_, y, fy, fr),
            };
            prop_assert_eq!(Product::new(kind, fx_, fy, fr).eval(x, y), want);
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
            prop_assert_eq!(Threshold::new(fx_, c).cmp(x), fx::cmp_const(x, fx_, c));
        }
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
                    assert_eq!(t.cmp(x), fx::cmp_const(x, f, c), "f {f} w {w} x {x}");
                }
            }
        }
    }
}
