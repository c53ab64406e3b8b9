//! What a board file (or a key map's board fields) may ask of the RP2040 the firmware runs
//! on: the chip's part of the one validation of a board. `tactus budget`, `build` and
//! `play` read every board through [`crate::boards::read_board`] (this check, then the
//! converter drivers planned for one key a core), and `tactus emu run` checks a key map's
//! clock, sample rate and cores with [`check_board`], so a board is either one the firmware
//! can be built and flashed for — and then every verdict about it is about real firmware —
//! or bad input naming the file and the field.
//!
//! A board file describes the machine only (`tactus_runtime::keyboard::BoardSpec`: name,
//! clock, cores, sample rate). Two levels:
//!
//! - [`image_board`]: what [`crate::image::FirmwareImage::build`] needs to lay an image
//!   out — 1 or 2 cores (the RP2040 has two; each core owns one SRAM bank and one scratch
//!   bank for its stack), a whole number of Hz of sample rate up to 1 MHz, a whole number
//!   of Hz of clock from 1 MHz, and a sample tick of [`MIN_PERIOD`] to 2²⁴ cycles (each
//!   core's SysTick, a 24-bit counter). The emulator runs such an image at any of these
//!   clocks (tests price boards at synthetic clocks);
//! - [`check_board`]: that, and a clock PLL_SYS makes from the 12 MHz crystal
//!   ([`tactus_rp2040::pll::pll_sys_dividers`]: REFDIV 1, FBDIV 16–320, VCO
//!   750–1600 MHz, post dividers 1–7; RP2040 datasheet 2.18), because the image's reset
//!   handler sets the clock with exactly those dividers. This is the rule of
//!   [`crate::image::FirmwareImage::flashable`], and so of `tactus build`.
//!
//! Whether the instruments accept the board's sample rate (their `require`s) is decided
//! where they are compiled, at that rate (`tactus_compiler::lower::Config::sample_rate_hz`).

use tactus_runtime::keyboard::BoardSpec;

/// The tick schedule in core clock cycles: the period is `q + rem/den` cycles
/// (`clock/fs`), each core's SysTick counting the processor clock with a reload value of
/// `q − 1` or `q` (periods of `q` or `q + 1` cycles) chosen by a remainder accumulator
/// `acc` in `[0, den)` (`image::glue::ctrl::ACC`): each period adds `rem` and is one cycle longer
/// when `acc` reaches `den`, so tick *n* is at cycle `first + ⌊n·clock/fs⌋`
/// (`tactus_runtime::keyboard::tick_cycle`) and the shortest period, the deadline, is `q`
/// (`tactus_runtime::keyboard::deadline_cycles`).
///
/// A write to SYST_RVR takes effect at the next reload (DDI0419 B3.3.1): the handler of
/// tick *n*, which runs after the reload that started period *n*, sets the reload value of
/// period *n* + 1. The start handler leaves `q − 1` for the first two periods (the first
/// accumulator step never carries: `rem < den`), and the control block's accumulator
/// starts at `rem`, period 1's.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Tick {
    /// Whole cycles per period: `clock div fs` (2 to 2²⁴).
    pub q: u32,
    /// The fraction's numerator: `clock mod fs` over the fraction's gcd (0: whole cycles).
    pub rem: u32,
    /// The fraction's denominator: `fs` over the same gcd (133 MHz / 44.1 kHz: 55/63).
    pub den: u32,
}

/// Fewest cycles per sample the image accepts: the start handler must have enabled each
/// core's SysTick before the first tick, `q` cycles after the enabling store.
pub const MIN_PERIOD: u64 = 100;

/// A board field the firmware cannot run with, and why.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct BoardError {
    /// The field (`clock_hz`, `sample_rate_hz`, `cores`, `core_voltage_v`).
    pub field: &'static str,
    /// What is wrong, with the value.
    pub why: String,
}

impl std::fmt::Display for BoardError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "`{}`: {}", self.field, self.why)
    }
}

impl std::error::Error for BoardError {}

/// A board as the firmware runs it.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Chip {
    /// Cores that run keys (1 or 2).
    pub cores: usize,
    /// Sample rate, Hz.
    pub sample_rate_hz: u32,
    /// Core clock, Hz.
    pub clock_hz: u64,
    /// The sample tick's schedule.
    pub tick: Tick,
}

fn bad(field: &'static str, why: String) -> BoardError {
    BoardError { field, why }
}

/// What an image needs of `board` (the module documentation's first level).
///
/// Errors: [`BoardError`] naming the field.
pub fn image_board(board: &BoardSpec) -> Result<Chip, BoardError> {
    let cores = board.cores;
    if !(1..=2).contains(&cores) {
        return Err(bad(
            "cores",
            format!("{cores} cores: the RP2040 has 2; the firmware runs keys on 1 or 2"),
        ));
    }
    let fs = board.sample_rate_hz;
    if !(fs >= 1.0 && fs.fract() == 0.0 && fs <= 1e6) {
        return Err(bad(
            "sample_rate_hz",
            format!("{fs} Hz: the sample tick needs a whole number of Hz up to 1 MHz"),
        ));
    }
    let clock = board.clock_hz;
    if !(clock >= 1e6 && clock.fract() == 0.0 && clock <= 1e10) {
        return Err(bad(
            "clock_hz",
            format!("{clock} Hz: need a whole number of Hz from 1 MHz"),
        ));
    }
    let (fs, clock) = (fs as u32, clock as u64);
    Ok(Chip {
        cores: cores as usize,
        sample_rate_hz: fs,
        clock_hz: clock,
        tick: tick_schedule(fs, clock)?,
    })
}

/// Greatest common divisor (Euclid; `gcd(0, b)` is `b`).
pub(crate) fn gcd(mut a: u64, mut b: u64) -> u64 {
    while b != 0 {
        (a, b) = (b, a % b);
    }
    a
}

/// The sample tick of a `clock_hz` core at `fs` samples per second: `q = ⌊clock/fs⌋`
/// cycles, and the fraction `rem/den` in lowest terms ([`Tick`]).
///
/// Errors: [`BoardError`] on `sample_rate_hz` when `q` is outside [`MIN_PERIOD`]…2²⁴ (the
/// SysTick's 24-bit reload) or `fs` is 0.
pub fn tick_schedule(fs: u32, clock_hz: u64) -> Result<Tick, BoardError> {
    let q = clock_hz.checked_div(u64::from(fs)).unwrap_or(0);
    if !(MIN_PERIOD..=1 << 24).contains(&q) {
        return Err(bad(
            "sample_rate_hz",
            format!(
                "{fs} Hz at a {clock_hz} Hz clock is {q} cycles per sample: the sample tick \
                 (SysTick, a 24-bit counter) needs {MIN_PERIOD} to {}",
                1u64 << 24
            ),
        ));
    }
    let rem = clock_hz % u64::from(fs);
    let x = gcd(rem, u64::from(fs));
    Ok(Tick {
        q: q as u32,
        rem: (rem / x) as u32,
        den: (u64::from(fs) / x) as u32,
    })
}

/// Why no PLL_SYS setting makes `clock_hz` from the 12 MHz crystal; `None` when one does.
pub fn pll_error(clock_hz: u64) -> Option<String> {
    match tactus_rp2040::pll::pll_sys_dividers(clock_hz) {
        Some(_) => None,
        None => Some(format!(
            "{clock_hz} Hz: no PLL_SYS setting makes it from the 12 MHz crystal (REFDIV 1, \
             FBDIV 16–320, VCO 750–1600 MHz, post dividers 1–7; e.g. 125 MHz, 133 MHz, \
             200 MHz, 20 MHz)"
        )),
    }
}

/// The board's clock and shape as the firmware runs it: [`image_board`] and a clock
/// PLL_SYS makes (what a key map's board fields can be checked against: a key map does
/// not record the core voltage, which the emulator checks when the firmware switches
/// clk_sys).
///
/// Errors: [`BoardError`] naming the field.
pub fn check_clock(board: &BoardSpec) -> Result<Chip, BoardError> {
    let chip = image_board(board)?;
    if let Some(why) = pll_error(chip.clock_hz) {
        return Err(bad("clock_hz", why));
    }
    Ok(chip)
}

/// Whether the firmware can be built and flashed for `board` (the module documentation's
/// second level): [`check_clock`], and a core voltage (`core_voltage_v`, 1.10 V when
/// absent) the RP2040 runs that clock at ([`tactus_rp2040::vreg::min_core_mv`]:
/// 1.10 V to 133 MHz, 1.15 V to 200 MHz, nothing above; pico-sdk 2.1.1) — the rule of
/// [`crate::image::FirmwareImage::flashable`].
///
/// A board that names `[converters]` must name parts the firmware drives, wired as its
/// drivers need (`tactus_runtime::converters::Converters::check`).
///
/// Errors: [`BoardError`] naming the field.
pub fn check_board(board: &BoardSpec) -> Result<Chip, BoardError> {
    use tactus_rp2040::vreg::{min_core_mv, DEFAULT_CORE_MV};
    if let Some(c) = &board.converters {
        // The parts the firmware drives and their wiring (`tactus_runtime::converters`);
        // what the keys need of them is checked where they are placed (`image::io`).
        c.check(&board.name, board.cores)
            .map_err(|why| bad("converters", why))?;
    }
    let chip = check_clock(board)?;
    let mhz = chip.clock_hz as f64 / 1e6;
    match min_core_mv(chip.clock_hz) {
        None => Err(bad(
            "clock_hz",
            format!("{mhz} MHz: beyond the 200 MHz the RP2040 is specified for (pico-sdk 2.1.1)"),
        )),
        Some(need) if board.core_mv().unwrap_or(DEFAULT_CORE_MV) < need => Err(bad(
            "core_voltage_v",
            format!(
                "{:.2} V at {mhz} MHz: the RP2040 needs {:.2} V for that clock (pico-sdk \
                 2.1.1); write `core_voltage_v = {:.2}`",
                f64::from(board.core_mv().unwrap_or(DEFAULT_CORE_MV)) / 1e3,
                f64::from(need) / 1e3,
                f64::from(need) / 1e3
            ),
        )),
        Some(_) => Ok(chip),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn board(clock_hz: f64, cores: u32, sample_rate_hz: f64) -> BoardSpec {
        BoardSpec {
            name: "t".into(),
            clock_hz,
            cores,
            sample_rate_hz,
            core_voltage_v: None,
            converters: None,
        }
    }

    #[test]
    fn each_field_is_named() {
        let field = |b: BoardSpec| check_board(&b).unwrap_err().field;
        assert_eq!(field(board(133.3e6, 2, 44_100.0)), "clock_hz");
        assert_eq!(field(board(133e6, 64, 44_100.0)), "cores");
        assert_eq!(field(board(133e6, 0, 44_100.0)), "cores");
        assert_eq!(field(board(133e6, 2, 44_100.5)), "sample_rate_hz");
        // 2 MHz: 66 cycles per sample, below the tick's minimum.
        assert_eq!(field(board(133e6, 2, 2e6)), "sample_rate_hz");
        assert_eq!(field(board(20e6, 2, 500_000.0)), "sample_rate_hz");
        let chip = check_board(&board(133e6, 2, 44_100.0)).unwrap();
        assert_eq!((chip.tick.q, chip.tick.rem, chip.tick.den), (3015, 55, 63));
        // Emulator-only clocks pass the image's level, not the board file's.
        assert!(image_board(&board(133.3e6, 2, 44_100.0)).is_ok());
        // 200 MHz needs 1.15 V.
        assert_eq!(field(board(200e6, 2, 44_100.0)), "core_voltage_v");
        let b = BoardSpec {
            core_voltage_v: Some(1.15),
            ..board(200e6, 2, 44_100.0)
        };
        assert!(check_board(&b).is_ok());
    }
}
