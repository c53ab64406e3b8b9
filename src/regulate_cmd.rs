//! `tactus regulate`: the regulation sheet of a key instrument
//! (`tactus_host::regulate::measure`), printed as a technician's table, the
//! force–travel loop plotted, and with `--spec` a verdict per figure.

use crate::check_cmd::{compile_reporting, parse_override};
use crate::source;
use std::path::PathBuf;
use std::process::ExitCode;
use tactus_host::regulate::sheet as host_regulate;
use tactus_host::regulate::{spec, Config, Figure};

/// Arguments of `tactus regulate`.
#[derive(Debug, clap::Args)]
#[command(after_long_help = figures_help())]
pub struct RegulateArgs {
    /// Instrument file or built-in name (grand_piano, harpsichord, harpsichord_2x8, hammond).
    #[arg(default_value = "grand_piano")]
    pub file: String,
    /// Override a param: `--param M_h=11 g` (repeatable), e.g. a key of a graded keyboard.
    #[arg(long = "param", value_name = "NAME=VALUE", value_parser = parse_override)]
    pub params: Vec<(String, String)>,
    /// A spec of ranges (TOML, e.g. instruments/specs/concert_grand.toml): a verdict per
    /// figure, exit 1 when one is outside its range or not measured.
    #[arg(long, value_name = "SPEC.toml")]
    pub spec: Option<PathBuf>,
    /// Arithmetic: `f64` (the reference semantics) or `fixed` (the firmware's fixed point,
    /// the fixed-point interpreter's bits).
    #[arg(long, value_enum, default_value = "f64")]
    pub numeric: crate::values::Numeric,
    /// Engine: `jit` (cranelift, bit-identical to the interpreter of the same numeric, and
    /// many times faster) or `interp` (the interpreters that define the semantics).
    #[arg(long, value_enum, default_value = "jit")]
    pub engine: crate::values::EngineKind,
    /// Directory for the force–travel loop (`NAME-loop.svg`, `NAME-loop.csv`).
    #[arg(long, short, default_value = "out")]
    pub out: PathBuf,
}

fn figures_help() -> String {
    let mut s = String::from(
        "Measured as a piano technician measures an action, on the instrument's own semantics with\n\
         the closed-loop key model (a 30 g key and finger at the key front, pushed by weights or\n\
         a finger, the instrument's force pushing back, one sample of delay as on the board).\n\
         The first sensor is the key travel (0 at rest, its upper bound the key bed); a hammer\n\
         action publishes `hammer_pos` and emits `strike`. Figures that do not apply are left out\n\
         with a note. Figures (name in a spec file, unit):\n",
    );
    for f in Figure::ALL {
        s.push_str(&format!(
            "  {:<22} {:<8} {}\n",
            f.key(),
            f.unit(),
            f.title()
        ));
    }
    s.push_str(
        "\nExit status: 0, or 1 when a figure is outside the spec's range (or not measured);\n\
         2 on bad input.\n\n\
         Examples: tactus regulate grand_piano --spec instruments/specs/concert_grand.toml\n\
         \x20         tactus regulate grand_piano --param M_h=11 g     # grand88's bass hammer\n\
         \x20         tactus regulate harpsichord --numeric fixed",
    );
    s
}

/// Runs `tactus regulate`.
pub fn run(args: RegulateArgs) -> ExitCode {
    match run_inner(&args) {
        Ok(code) => code,
        Err(e) => {
            eprintln!("error: {e}");
            ExitCode::from(2)
        }
    }
}

fn run_inner(args: &RegulateArgs) -> Result<ExitCode, String> {
    // The spec first: a mistake in it fails before the measuring.
    let spec = args.spec.as_deref().map(spec::read).transpose()?;
    let src = source::load(&args.file)?;
    let Some(lowered) =
        compile_reporting(&src, &args.params, tactus_runtime::DEFAULT_SAMPLE_RATE_HZ)
    else {
        return Ok(ExitCode::from(2));
    };
    let config = Config::default();
    let (sheet, warnings) = host_regulate::measure(
        &lowered.program,
        args.numeric.into(),
        args.engine.into(),
        &config,
    )?;
    source::report(&src, &warnings);
    let numeric = match args.numeric {
        crate::values::Numeric::F64 => "f64 semantics",
        crate::values::Numeric::Fixed => "fixed point",
    };
    println!(
        "{} — regulation sheet ({numeric}; closed-loop key of {:.0} g at the key front)",
        sheet.instrument,
        config.finger.mass_kg * 1e3
    );
    let verdicts = spec.as_ref().map(|s| spec::check(&sheet, s));
    print!("{}", host_regulate::sheet_text(&sheet, verdicts.as_deref()));
    let (svg, csv) = host_regulate::write_loop(&sheet, &args.out)?;
    println!("  wrote {} (force–travel loop)", svg.display());
    println!("  wrote {}", csv.display());
    let (Some(spec), Some(verdicts)) = (spec, verdicts) else {
        return Ok(ExitCode::SUCCESS);
    };
    let (holds, line) = host_regulate::spec_line(&spec, &verdicts);
    println!("{line}");
    Ok(if holds {
        ExitCode::SUCCESS
    } else {
        ExitCode::FAILURE
    })
}
