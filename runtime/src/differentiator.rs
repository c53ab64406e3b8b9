//! The multi-sample differentiators behind `d()` and `d2()`.
//!
//! MIKEY estimates key velocity and acceleration from the 16-bit position samples with
//! multi-sample differentiators; a one-sample difference would turn one ADC step of a 10 mm
//! key (0.15 µm) into 6.7 mm/s of velocity noise at 44.1 kHz. Tactus uses backward
//! differences over a window of [`WINDOW`] samples:
//!
//! * `d(x)[n]  = (x[n] − x[n−N]) · fs / N` — velocity, group delay N/2 samples
//!   (90.7 µs at 44.1 kHz, N = 8), quantisation noise divided by N;
//! * `d2(x)[n] = (x[n] − 2·x[n−N] + x[n−2N]) · (fs / N)²` — acceleration, delay N samples.
//!
//! N is a power of two so a fixed-point engine can scale by a shift. Before the first
//! sample the history is taken to be the first sample itself (the key was at rest there), so
//! both derivatives start at zero. Every engine must compute exactly these formulas.

/// The differentiator window N, in samples.
pub const WINDOW: usize = 8;
const HISTORY: usize = 2 * WINDOW + 1;

/// The last `2N + 1` readings of one sensor, newest last; before the first reading the
/// history is primed with it. `History<f64>` serves the f64 engines, `History<i32>` (raw
/// words) the fixed-point ones.
#[derive(Clone, Debug, PartialEq)]
pub struct History<T> {
    hist: [T; HISTORY],
    /// Index of the newest sample in `hist`.
    pos: usize,
    primed: bool,
}

impl<T: Copy + Default> Default for History<T> {
    fn default() -> Self {
        History {
            hist: [T::default(); HISTORY],
            pos: 0,
            primed: false,
        }
    }
}

impl<T: Copy> History<T> {
    /// Takes this sample's reading.
    pub fn push(&mut self, x: T) {
        if !self.primed {
            self.hist = [x; HISTORY];
            self.primed = true;
        }
        self.pos = (self.pos + 1) % HISTORY;
        self.hist[self.pos] = x;
    }

    /// The reading `k` samples ago (0 = newest), `k <= 2N`.
    fn ago(&self, k: usize) -> T {
        self.hist[(self.pos + HISTORY - k) % HISTORY]
    }
}

/// History of one sensor for `d()`/`d2()` in the f64 engines.
pub type Differentiator = History<f64>;

impl History<f64> {
    /// `d(x)`: first derivative at sample rate `fs` (Hz), unit of x per second.
    pub fn d1(&self, fs: f64) -> f64 {
        (self.ago(0) - self.ago(WINDOW)) * (fs / WINDOW as f64)
    }

    /// `d2(x)`: second derivative at sample rate `fs` (Hz), unit of x per second squared.
    pub fn d2(&self, fs: f64) -> f64 {
        let r = fs / WINDOW as f64;
        (self.ago(0) - 2.0 * self.ago(WINDOW) + self.ago(2 * WINDOW)) * r * r
    }
}

/// The history for fixed-point engines: raw sensor words. The fixed-point derivative is
/// `x[n] − x[n−N]` (resp. `x[n] − 2·x[n−N] + x[n−2N]`) taken exactly on the raw words, then
/// multiplied by `fs/N` (resp. `(fs/N)²`) with the rounding rule of [`crate::fixed`].
pub type RawHistory = History<i32>;

impl History<i32> {
    /// `x[n] − x[n−N]`, exact.
    pub fn diff1(&self) -> i64 {
        self.ago(0) as i64 - self.ago(WINDOW) as i64
    }

    /// `x[n] − 2·x[n−N] + x[n−2N]`, exact.
    pub fn diff2(&self) -> i64 {
        self.ago(0) as i64 - 2 * self.ago(WINDOW) as i64 + self.ago(2 * WINDOW) as i64
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ramp_and_parabola_are_exact() {
        let fs = 44_100.0;
        let mut d = Differentiator::default();
        for n in 0..100 {
            let t = n as f64 / fs;
            d.push(0.3 * t + 2.0 * t * t);
        }
        let t = 99.0 / fs;
        let lag = WINDOW as f64 / fs;
        // Backward difference of a parabola: exact slope at the window's midpoint.
        let v_mid = 0.3 + 4.0 * (t - lag / 2.0);
        assert!((d.d1(fs) - v_mid).abs() < 1e-9, "{}", d.d1(fs));
        assert!((d.d2(fs) - 4.0).abs() < 1e-6, "{}", d.d2(fs));
    }

    #[test]
    fn starts_at_rest() {
        let mut d = Differentiator::default();
        d.push(0.005);
        assert_eq!(d.d1(44_100.0), 0.0);
        assert_eq!(d.d2(44_100.0), 0.0);
    }
}
