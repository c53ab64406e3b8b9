//! The cycles-and-sizes table of `cargo run --release -p tactus-firmware --example compilers`,
//! one row per instrument and engine, so that further engines (the Thumb backend) are
//! further rows of the same table.

use crate::measure::Comparison;
use std::fmt::Write as _;

/// One engine's result on one instrument.
#[derive(Clone, Debug)]
pub struct Row {
    /// The instrument.
    pub instrument: String,
    /// The engine (`"clang -O2"`, `"gcc -O2"`, `"thumb"`).
    pub engine: String,
    /// Its comparison with the fixed interpreter over the stimuli.
    pub comparison: Comparison,
    /// The update function's code size, bytes, if known.
    pub update_bytes: Option<u32>,
    /// All code linked for the update (helpers included), bytes, if known.
    pub with_helpers_bytes: Option<u32>,
}

/// Formats rows as a Markdown table: instrument, engine, worst and mean cycles per
/// key-sample (including the call's `BL` and the return), the share of the per-sample
/// deadline of one core of the emulated board's default clock at 44.1 kHz (2,926 cycles at
/// 133 MHz, [`tactus_runtime::keyboard::deadline_cycles`]) that the worst case takes, code
/// bytes (update / with helpers), samples compared and mismatches.
pub fn table(rows: &[Row]) -> String {
    let deadline = tactus_runtime::keyboard::deadline_cycles(
        tactus_emulator::Config::default().clock_hz as f64,
        44_100.0,
    );
    let mut s = String::new();
    let _ = writeln!(
        s,
        "| instrument | engine | worst cycles | mean cycles | worst / {deadline} | .text update | .text with helpers | samples | mismatches |"
    );
    let _ = writeln!(s, "|---|---|---:|---:|---:|---:|---:|---:|---:|");
    let opt = |b: Option<u32>| b.map_or("–".to_string(), |b| b.to_string());
    for r in rows {
        let c = &r.comparison;
        let _ = writeln!(
            s,
            "| {} | {} | {} | {:.1} | {:.1} % | {} | {} | {} | {} |",
            r.instrument,
            r.engine,
            c.cycles.worst,
            c.cycles.mean(),
            100.0 * c.cycles.worst as f64 / deadline as f64,
            opt(r.update_bytes),
            opt(r.with_helpers_bytes),
            c.samples,
            c.mismatches
        );
    }
    s
}
