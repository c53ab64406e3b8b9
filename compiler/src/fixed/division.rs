//! Run-time divisions: how far a divisor may be pre-shifted ([`DIV_REL_TOLERANCE`]) so that
//! the quotient runs on the RP2040's 32÷32 SIO divider in few digits
//! ([`sio_division_steps`]).

use super::*;

/// A run-time division may shift its divisor right ([`tactus_runtime::fixed::div_shifted`])
/// when the dropped bits cost at most this relative error of the quotient (2^-10). The shift
/// frees quotient digits per division of the RP2040's 32÷32 SIO divider
/// ([`sio_division_steps`]). Chosen by the accuracy contract ([`contract`], checked in
/// `compiler/tests/contract.rs`): on the grand piano's built-in stimuli the worst force error
/// is 0.12 DAC LSB at 2^-16 and 2^-12, 0.19 at 2^-10, 0.76 at 2^-8 and 1.12 (broken) at 2^-6
/// (its two divisions set the impact pulse's decay time and rate).
pub const DIV_REL_TOLERANCE: f64 = 1.0 / 1024.0;

/// Divisors are not shifted below this many significant bits: at 16, two hardware divisions
/// give any quotient of up to 32 bits, so more shifting buys nothing.
pub const DIV_MIN_DIVISOR_BITS: i32 = 16;

/// Number of bits of a raw magnitude bound `m` (`ceil(log2(m + 1))`): 0 for 0.
pub fn bits_of(m: u64) -> i32 {
    64 - m.leading_zeros() as i32
}

/// Hardware divisions a long division by the RP2040's 32÷32 unsigned divider takes for a
/// quotient of `quotient_bits` bits and a divisor of `divisor_bits` bits: digits of
/// `s = 32 − divisor_bits` bits (each step divides the remainder with the next `s` dividend
/// bits appended), `ceil(quotient_bits / s)` steps. `None` for a divisor of 32 bits or more
/// (no digit fits). One definition, used by the Thumb backend and the precision report.
pub fn sio_division_steps(quotient_bits: i32, divisor_bits: i32) -> Option<u32> {
    let s = 32 - divisor_bits;
    if s <= 0 {
        return None;
    }
    Some((quotient_bits.max(1) + s - 1) as u32 / s as u32)
}

/// The divisor pre-shift of a run-time division (see [`DIV_REL_TOLERANCE`]): the largest `b`
/// with `2^b ≤ DIV_REL_TOLERANCE · min |y raw|` that leaves the divisor at least
/// [`DIV_MIN_DIVISOR_BITS`] bits and at least 4 after the shift, and keeps the quotient with
/// the shifted divisor below 2^31 in the result format. 0 when the divisor's range contains
/// 0 (no shift is safe then).
pub(super) fn plan_div_shift(fy: i32, ry: Interval, fr: i32, rv: Interval, tolerance: f64) -> u8 {
    let scale = 2f64.powi(fy);
    let (lo, hi) = (ry.lo * scale, ry.hi * scale);
    let ymin = if lo > 0.0 {
        lo
    } else if hi < 0.0 {
        -hi
    } else {
        return 0;
    };
    let ymax = ry.mag() * scale;
    if !(ymin.is_finite() && ymax.is_finite()) || ymin < 1.0 {
        return 0;
    }
    let lmax = bits_of(ymax.ceil() as u64);
    let mut b = ((tolerance * ymin).log2().floor() as i32)
        .min(lmax - DIV_MIN_DIVISOR_BITS)
        .clamp(0, 30);
    let q = rv.mag() * 2f64.powi(fr);
    while b > 0
        && (q * (1.0 + 2f64.powi(b + 1) / ymin) + 2.0 >= 2147483648.0 || ymin < 4.0 * 2f64.powi(b))
    {
        b -= 1;
    }
    b as u8
}
