//! `tactus check`: parse and check an instrument, print its diagnostics (and the IR).

use crate::source;
use std::process::ExitCode;
use tactus_host::check;
use tactus_runtime::DEFAULT_SAMPLE_RATE_HZ;

/// Arguments of `tactus check`.
#[derive(Debug, clap::Args)]
pub struct CheckArgs {
    /// Instrument file (`instruments/grand_piano.tactus`) or built-in name (`grand_piano`).
    pub file: String,
    /// Override a param: `--param k=200 N/m` (repeatable; the unit must match the param's).
    #[arg(long = "param", value_name = "NAME=VALUE", value_parser = parse_override)]
    pub params: Vec<(String, String)>,
    /// Also print the lowered IR.
    #[arg(long, value_enum)]
    pub emit: Option<Emit>,
    /// Print a report: `precision` gives the range, Q-format and error bound (N and DAC
    /// LSB) of every state and force term of the fixed-point build, and its multiply cost.
    #[arg(long, value_enum)]
    pub report: Option<Report>,
}

/// What `--report` prints.
#[derive(Clone, Copy, Debug, clap::ValueEnum)]
pub enum Report {
    /// Fixed-point ranges, formats and error bounds.
    Precision,
}

/// What `--emit` prints.
#[derive(Clone, Copy, Debug, clap::ValueEnum)]
pub enum Emit {
    /// The IR after lowering (instanced components, SI constants).
    Ir,
}

/// Parses `NAME=VALUE` of `--param`.
pub fn parse_override(s: &str) -> Result<(String, String), String> {
    match s.split_once('=') {
        Some((n, v)) if !n.trim().is_empty() && !v.trim().is_empty() => {
            Ok((n.trim().to_string(), v.trim().to_string()))
        }
        _ => Err(format!(
            "expected NAME=VALUE with a unit, e.g. `k=200 N/m`, got `{s}`"
        )),
    }
}

/// Compiles a source with overrides for a board sampling at `sample_rate_hz` (Hz; its
/// `require`s see it, its dynamics are discretised at it) and prints its diagnostics to
/// stderr; returns the IR.
pub fn compile_reporting(
    src: &source::Source,
    params: &[(String, String)],
    sample_rate_hz: f64,
) -> Option<tactus_compiler::lower::Lowered> {
    tactus_host::keyboard::lower(src, params, sample_rate_hz, &mut source::report_compile)
}

/// Runs `tactus check`.
pub fn run(args: CheckArgs) -> ExitCode {
    let src = match source::load(&args.file) {
        Ok(s) => s,
        Err(e) => {
            eprintln!("error: {e}");
            return ExitCode::FAILURE;
        }
    };
    let Some(l) = compile_reporting(&src, &args.params, DEFAULT_SAMPLE_RATE_HZ) else {
        return ExitCode::FAILURE;
    };
    let p = &l.program;
    println!("{}", check::summary(&src, p));
    if matches!(args.emit, Some(Emit::Ir)) {
        print!("{p}");
    }
    if matches!(args.report, Some(Report::Precision)) {
        let precision = check::precision(p);
        source::report(&src, &precision.warnings);
        print!("{}", precision.text);
        // A broken contract is a failure, as `build` refuses the instrument.
        if let Some(b) = precision.broken {
            eprintln!("error: {}: {b}", src.name);
            return ExitCode::FAILURE;
        }
    }
    ExitCode::SUCCESS
}
