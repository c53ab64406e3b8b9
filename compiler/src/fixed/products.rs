//! The product algebra: how a multiplication of two fixed-point words is done on a core
//! whose `MULS` keeps only the low 32 bits ([`MulKind`]: pre-shifted `MULS`, 32×16, the high
//! word of 32×32, the exact 64-bit product), which operand a 32×16 form cuts ([`Cut`]), and
//! the error each form adds for a product's operands ([`MulOperands`]) — what the planner
//! chooses between. The forms' bits are defined in `tactus_runtime::fixed`.

use super::*;

/// A multiplication may drop low operand bits to fit `MULS` when the error this adds is at
/// most this fraction of the product's largest magnitude (2^-22: 6 bits finer than a 16-bit
/// DAC at full scale).
pub const MULS_REL_TOLERANCE: f64 = 1.0 / (1u64 << 22) as f64;

/// The operands of one product as the plan sees them: each operand's format and range, and
/// the number of its low bits known to be zero (a constant's trailing zeros), which shift
/// off exactly.
#[derive(Clone, Copy, Debug)]
pub(super) struct MulOperands {
    pub(super) x: (i32, Interval),
    pub(super) free_x: i32,
    pub(super) y: (i32, Interval),
    pub(super) free_y: i32,
    /// Whether `y` is a constant (its word known at compile time).
    pub(super) constant: bool,
    pub(super) result: Interval,
    /// The result's fraction bits.
    pub(super) fr: i32,
}

impl MulOperands {
    /// The pre-shifts `(a, b)` that fit the product in 31 bits and their absolute error.
    pub(super) fn shifts(&self) -> Option<(i32, i32, f64)> {
        let ((fx, rx), (fy, ry)) = (self.x, self.y);
        let (free_x, free_y) = (self.free_x, self.free_y);
        let bits = |f: i32, r: Interval| (r.mag() * 2f64.powi(f)).max(1.0).log2().ceil() as i32;
        let (mut a, mut b) = (0i32, 0i32);
        let (bx, by) = (bits(fx, rx), bits(fy, ry));
        while (bx - a) + (by - b) > 31 && a < 31 && b < 31 {
            if a < free_x {
                a += 1;
            } else if b < free_y {
                b += 1;
            } else if bx - a >= by - b {
                a += 1;
            } else {
                b += 1;
            }
        }
        if (bx - a) + (by - b) > 31 {
            return None;
        }
        let shift_err = |s: i32, f: i32, free: i32| if s <= free { 0.0 } else { 2f64.powi(s - f) };
        let (ex, ey) = (shift_err(a, fx, free_x), shift_err(b, fy, free_y));
        Some((a, b, ry.mag() * ex + rx.mag() * ey + ex * ey))
    }

    /// The high-word form ([`MulKind::High`]): the smallest `k` in 16..=32 for which the
    /// partial-product sum `p` of [`tactus_runtime::fixed::mul_high`] fits a signed 32-bit
    /// word, and its absolute error (`(2 + 2^(32−k))·2^(k − fx − fy)`, SI).
    pub(super) fn high(&self) -> Option<(u8, f64)> {
        let ((fx, rx), (fy, ry)) = (self.x, self.y);
        let word = |f: i32, r: Interval| (r.mag() * 2f64.powi(f) * (1.0 + 1e-9)).ceil() + 1.0;
        let (bx, by) = (word(fx, rx), word(fy, ry));
        if !(bx.is_finite() && by.is_finite()) || bx > 2147483648.0 || by > 2147483648.0 {
            return None;
        }
        // Bounds of the high halves: |x >> 16| ≤ floor(bx / 2^16) + 1.
        let (hx, hy) = ((bx / 65536.0).floor() + 1.0, (by / 65536.0).floor() + 1.0);
        (16..=32).find_map(|k: i32| {
            let p = (hx * hy + hx + hy) * 2f64.powi(32 - k) + 2.0;
            (p < 2147483647.0)
                .then(|| (k as u8, (2.0 + 2f64.powi(32 - k)) * 2f64.powi(k - fx - fy)))
        })
    }

    /// The 32×16 form ([`MulKind::Mul32x16`]) cutting the pair's second operand (`cut_y`) or
    /// its first: the smallest pre-shift `b` that leaves the cut word a signed 16-bit half
    /// (`|word| < 2^(15+b)`); the unit `2^k` of the partial-product sum `p` of
    /// [`tactus_runtime::fixed::mul_32x16`] that makes `p`'s format the result's (its floor
    /// then is the rounding, one `ASRS` instead of a rounding shift after the sum: an error
    /// of one result LSB where the cut costs 2^15 times more), within 0..=16 and not below
    /// the smallest `k` for which every part of `p` and `p` itself fit a signed 32-bit word;
    /// and the absolute error (SI): the kept operand's magnitude times one LSB of the cut
    /// word (`|x|·2^(b − fy)`, 0 when the dropped bits are known zeros) plus the floor's
    /// `2^(b + k − fx − fy)`. `None` when an operand is unbounded.
    pub(super) fn half(&self, cut_y: bool) -> Option<(u8, u8, f64)> {
        let ((fk, rk), (fc, rc), free) = if cut_y {
            (self.x, self.y, self.free_y)
        } else {
            (self.y, self.x, self.free_x)
        };
        let word = |f: i32, r: Interval| (r.mag() * 2f64.powi(f) * (1.0 + 1e-9)).ceil() + 1.0;
        let (bk, bc) = (word(fk, rk), word(fc, rc));
        if !(bk.is_finite() && bc.is_finite()) || bk > 2147483648.0 || bc > 2147483648.0 {
            return None;
        }
        let b = (0..=16).find(|&b| bc < 2f64.powi(15 + b))?;
        // Bounds of |ys| (≤ 2^15) and of the kept word's high half |xh|.
        let ys = ((bc / 2f64.powi(b)).floor() + 1.0).min(32768.0);
        let hk = (bk / 65536.0).floor() + 1.0;
        let kmin = (0..=16).find(|&k| {
            let high = hk * ys * 2f64.powi(16 - k);
            let low = (65535.0 * ys / 2f64.powi(k)).ceil();
            high + low + 1.0 < 2147483647.0
        })?;
        let k = (fk + fc - b - self.fr).clamp(kmin, 16);
        let cut = if b > free {
            rk.mag() * 2f64.powi(b - fc)
        } else {
            0.0
        };
        Some((b as u8, k as u8, cut + 2f64.powi(b + k - fk - fc)))
    }

    /// The 32×16 forms of the product in operand order (`swapped`: the plan's pair is
    /// (y, x)), the smaller error first: a product by a constant cuts the constant; two
    /// run-time operands may cut either, and the error analysis decides
    /// ([`FixedProgram::spend_precision_budget`]).
    pub(super) fn halves(&self, swapped: bool) -> Vec<MulKind> {
        let mut out: Vec<(f64, MulKind)> = [true, false]
            .into_iter()
            .filter(|&cut_y| cut_y || !self.constant)
            .filter_map(|cut_y| {
                let (b, k, err) = self.half(cut_y)?;
                let second = cut_y != swapped;
                let cut = if second { Cut::Second } else { Cut::First };
                Some((err, MulKind::Mul32x16 { cut, b, k }))
            })
            .collect();
        out.sort_by(|a, b| a.0.total_cmp(&b.0));
        out.into_iter().map(|(_, k)| k).collect()
    }

    /// Plans the product: shift free bits first, then the operand with more significant
    /// bits, until the product fits 31 bits. With `tolerance`, accept only when the floor
    /// shifts cost at most [`MULS_REL_TOLERANCE`] of the result's magnitude, else the 64-bit
    /// product; without, always `MULS` where the shifts exist. The precision budget then
    /// tries the cheaper forms ([`MulOperands::high`] among them) on the 64-bit ones.
    /// The shifts are returned in operand order (`swapped`: the plan's pair is (y, x)).
    pub(super) fn plan(&self, swapped: bool, tolerance: bool) -> MulKind {
        let limit = MULS_REL_TOLERANCE * self.result.mag().max(f64::MIN_POSITIVE);
        if let Some((a, b, err)) = self.shifts() {
            if !tolerance || err <= limit {
                return if swapped {
                    MulKind::Muls(b as u8, a as u8)
                } else {
                    MulKind::Muls(a as u8, b as u8)
                };
            }
        }
        let _ = tolerance;
        MulKind::Wide
    }
}

/// Which operand of a product a [`MulKind::Mul32x16`] cuts to 16 bits, in operand order
/// (`x · y`: `First` is `x`; for a division by a constant, `Second` is the reciprocal).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Cut {
    /// The first operand.
    First,
    /// The second operand.
    Second,
}

impl Cut {
    /// The operands `(x, y)` of a product as `(kept, cut)`: how every engine passes them to
    /// [`tactus_runtime::fixed::mul_32x16`] (its `y` is the cut one).
    pub fn kept_cut<T>(self, x: T, y: T) -> (T, T) {
        match self {
            Cut::First => (y, x),
            Cut::Second => (x, y),
        }
    }
}

/// How a multiplication is done on a 32-bit core without a 64-bit product instruction,
/// cheapest first. A 16×16 product is `Muls(0, 0)` (its operands already fit).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum MulKind {
    /// Operands pre-shifted right by (a, b) bits so the product fits 32 bits: one `MULS`
    /// plus shifts ([`tactus_runtime::fixed::mul_shifted`]).
    Muls(u8, u8),
    /// One operand (`cut`) pre-shifted right by `b` bits to a signed 16-bit half, the other
    /// kept whole as its two halves: two 16×16 `MULS`, the low one floored by `k` bits
    /// ([`tactus_runtime::fixed::mul_32x16`]).
    Mul32x16 {
        /// The operand cut to 16 bits.
        cut: Cut,
        /// Its pre-shift (bits).
        b: u8,
        /// The sum's unit `2^k` (0..=16).
        k: u8,
    },
    /// The high word of the 32×32 product in units of `2^k`: three 16×16 `MULS` partial
    /// products, two floored, the low one dropped, summed in 32 bits
    /// ([`tactus_runtime::fixed::mul_high`]).
    High(u8),
    /// The exact product needs up to 64 bits: four 16×16 `MULS` partial products and adds
    /// (ARMv6-M has no `SMULL`).
    Wide,
}

impl MulKind {
    /// The same form with the operands exchanged (`y · x` for `x · y`): the pre-shifts and
    /// the cut side follow their operands.
    pub fn swapped(self) -> MulKind {
        match self {
            MulKind::Muls(a, b) => MulKind::Muls(b, a),
            MulKind::Mul32x16 { cut, b, k } => MulKind::Mul32x16 {
                cut: match cut {
                    Cut::First => Cut::Second,
                    Cut::Second => Cut::First,
                },
                b,
                k,
            },
            k => k,
        }
    }

    /// The form's name in the precision report.
    pub fn name(self) -> String {
        match self {
            MulKind::Muls(0, 0) => "MULS 32×32→32 (operands fit)".into(),
            MulKind::Muls(a, b) => format!("pre-shifted MULS (>>{a}, >>{b})"),
            MulKind::Mul32x16 { cut, b, k } => format!(
                "32×16 (2 MULS, {} >>{b}, units of 2^{k})",
                match cut {
                    Cut::First => "x",
                    Cut::Second => "y",
                }
            ),
            MulKind::High(k) => format!("high word of 32×32 (3 MULS, units of 2^{k})"),
            MulKind::Wide => "64-bit product (4 MULS)".into(),
        }
    }
}

/// Products per form ([`MulKind`]) of a plan and their estimated Cortex-M0+ cycles
/// ([`FixedProgram::mul_forms`]).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct MulForms {
    /// `MULS` products (16×16 or pre-shifted).
    pub muls: usize,
    /// 32×16 products.
    pub m32x16: usize,
    /// High words of 32×32.
    pub high: usize,
    /// Full 64-bit products.
    pub wide: usize,
    /// Estimated cycles of all ([`MulKind::cycles`]).
    pub cycles: u32,
}

impl std::fmt::Display for MulForms {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "{} MULS, {} 32×16, {} high word, {} 64-bit (≈ {} cycles)",
            self.muls, self.m32x16, self.high, self.wide, self.cycles
        )
    }
}
