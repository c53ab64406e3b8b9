//! A small deterministic pseudo-random generator for stimuli with noise and for tests.
//!
//! xorshift64* (Vigna, "An experimental exploration of Marsaglia's xorshift generators,
//! scrambled", ACM TOMS 42(4), 2016): fast, reproducible from its seed on every platform,
//! statistically good enough for sensor noise and randomised tests — not for cryptography.

/// xorshift64* state. The seed must not be 0 (0 is replaced by a fixed constant).
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct XorShift64(u64);

impl XorShift64 {
    /// A generator from a seed.
    pub fn new(seed: u64) -> Self {
        XorShift64(if seed == 0 {
            0x9E37_79B9_7F4A_7C15
        } else {
            seed
        })
    }

    /// The next 64 random bits.
    pub fn next_u64(&mut self) -> u64 {
        self.0 ^= self.0 >> 12;
        self.0 ^= self.0 << 25;
        self.0 ^= self.0 >> 27;
        self.0.wrapping_mul(0x2545_F491_4F6C_DD1D)
    }

    /// A uniform integer in `0..n` (0 when `n` is 0).
    pub fn below(&mut self, n: usize) -> usize {
        (self.next_u64() % n.max(1) as u64) as usize
    }

    /// A uniform real in `[0, 1)`.
    pub fn unit(&mut self) -> f64 {
        (self.next_u64() >> 11) as f64 / (1u64 << 53) as f64
    }

    /// One of the corner words of a sensor whose raw range is `[lo, hi]`: `i32::MIN`,
    /// `i32::MAX`, the bounds, one past each, 0 — uniformly.
    pub fn corner_word(&mut self, (lo, hi): (i32, i32)) -> i32 {
        [
            i32::MIN,
            i32::MAX,
            lo,
            hi,
            lo.saturating_sub(1),
            hi.saturating_add(1),
            0,
        ][self.below(7)]
    }

    /// An adversarial raw sensor word for engine comparisons, given the previous word and
    /// the sensor's raw range `[lo, hi]`: 1/8 an arbitrary 32-bit word, 1/8 uniform in
    /// range, 1/8 a corner (`i32::MIN`, `i32::MAX`, the bounds, one past each, 0), else a
    /// small random-walk step from `prev` kept in range.
    pub fn sensor_word(&mut self, prev: i32, (lo, hi): (i32, i32)) -> i32 {
        let span = (hi as i64 - lo as i64).max(1) as u64;
        match self.below(8) {
            0 => self.next_u64() as i32,
            1 => (lo as i64 + (self.next_u64() % (span + 1)) as i64) as i32,
            2 => self.corner_word((lo, hi)),
            _ => {
                let step = ((self.next_u64() % (span / 200 + 2)) as i64) - (span / 400) as i64;
                (prev as i64 + step).clamp(lo as i64, hi as i64) as i32
            }
        }
    }
}
