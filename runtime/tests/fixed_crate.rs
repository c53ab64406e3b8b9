//! An independent cross-check of `tactus_runtime::fixed` (the definition of every engine's
//! bits) against the `fixed` crate, on the operations whose rounding coincides: addition,
//! subtraction and negation in one format (exact, saturating), format conversion and
//! multiplication rounded half up (the `fixed` crate's exact `wide_mul` and conversions,
//! which floor, with the half added explicitly), and comparison.
//!
//! Where it does not fit: division (ours truncates toward zero, as the RP2040's SIO divider
//! does; the crate's rounds differently), `sqrt`/`exp` (ours are integer algorithms of their
//! own) and formats with more than 32 or fewer than 0 fraction bits (the crate's fraction
//! counts are type parameters from 0 to the word size).

use fixed::types::{I16F16, I24F8, I32F32, I8F24};
use tactus_runtime::fixed as ours;
use tactus_runtime::rng::XorShift64;

/// Edge words, then random ones.
fn words(n: usize, seed: u64) -> Vec<i32> {
    let mut rng = XorShift64::new(seed);
    let mut v = vec![
        0,
        1,
        -1,
        i32::MAX,
        i32::MIN,
        i32::MAX - 1,
        i32::MIN + 1,
        1 << 15,
        -(1 << 15),
    ];
    v.extend((0..n).map(|_| rng.next_u64() as i32));
    // Small magnitudes too (products and sums that do not saturate).
    v.extend((0..n).map(|_| (rng.next_u64() as i32) >> (rng.below(24) + 1)));
    v
}

#[test]
fn addition_subtraction_negation_in_one_format() {
    let w = words(20_000, 1);
    for pair in w.chunks(2) {
        let [x, y] = [pair[0], pair.get(1).copied().unwrap_or(7)];
        let (a, b) = (I16F16::from_bits(x), I16F16::from_bits(y));
        assert_eq!(
            ours::add(x, 16, y, 16, 16).0,
            a.saturating_add(b).to_bits(),
            "{x} + {y}"
        );
        assert_eq!(
            ours::sub(x, 16, y, 16, 16).0,
            a.saturating_sub(b).to_bits(),
            "{x} - {y}"
        );
        assert_eq!(ours::neg(x, 16, 16).0, a.saturating_neg().to_bits(), "-{x}");
        assert_eq!(ours::cmp(x, 16, y, 16), a.cmp(&b), "{x} <> {y}");
    }
}

#[test]
fn conversion_rounds_half_up_as_floor_of_value_plus_half() {
    for x in words(40_000, 2) {
        // Q15.16 → Q23.8: floor(v + 2^-9), saturated.
        let v = I32F32::from(I16F16::from_bits(x)) + I32F32::from_bits(1 << (32 - 9));
        let want = v.saturating_to_num::<I24F8>().to_bits();
        assert_eq!(ours::convert(x, 16, 8).0, want, "{x}");
        // Q23.8 → Q7.24: exact, saturated.
        let want = I24F8::from_bits(x).saturating_to_num::<I8F24>().to_bits();
        assert_eq!(ours::convert(x, 8, 24).0, want, "{x}");
    }
}

#[test]
fn multiplication_is_the_exact_product_rounded_once_half_up() {
    let w = words(20_000, 3);
    for pair in w.chunks(2) {
        let [x, y] = [pair[0], pair.get(1).copied().unwrap_or(3)];
        // Q7.24 × Q15.16 → Q15.16: the exact product (I48F80 bits as i128) plus half an
        // output step, floored, saturated.
        let exact = i128::from(I8F24::from_bits(x).wide_mul(I16F16::from_bits(y)).to_bits());
        let s = 24 + 16 - 16;
        let rounded = (exact + (1i128 << (s - 1))) >> s;
        let want = rounded.clamp(i128::from(i32::MIN), i128::from(i32::MAX)) as i32;
        assert_eq!(ours::mul(x, 24, y, 16, 16).0, want, "{x} · {y}");
        assert_eq!(
            ours::mul(x, 24, y, 16, 16).1,
            rounded != i128::from(want),
            "{x} · {y}: overflow flag"
        );
    }
}
