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
    /// Instrument file or built-in name (grand_piano, harpsichord, harpsichord_2x8, hammond)
    /// [default: grand_piano, or with `--layout` the key's instrument].
    pub file: Option<String>,
    /// Override a param: `--param M_h=11 g` (repeatable); with `--layout`, on top of the key's
    /// graded params.
    #[arg(long = "param", value_name = "NAME=VALUE", value_parser = parse_override)]
    pub params: Vec<(String, String)>,
    /// Regulate one key of a keyboard layout (a `.toml` file or a built-in name, `grand88`):
    /// its instrument with its graded params, as the keyboard compiles it. Needs `--key`.
    #[arg(long, value_name = "LAYOUT", requires = "key", conflicts_with = "file")]
    pub layout: Option<String>,
    /// The key of `--layout` to regulate, a MIDI number (grand88: 21 = A0 … 108 = C8).
    #[arg(long, value_name = "MIDI", requires = "layout")]
    pub key: Option<u8>,
    /// A spec of ranges (TOML, e.g. instruments/specs/concert_grand.toml, or the dynamic
    /// one, concert_grand_dynamic.toml; repeatable): a verdict per figure, exit 1 when one is
    /// outside its range or not measured.
    #[arg(long, value_name = "SPEC.toml")]
    pub spec: Vec<PathBuf>,
    /// Leave out the dynamic sheet (the sweep of pressed and struck touches).
    #[arg(long)]
    pub no_dynamic: bool,
    /// Arithmetic: `f64` (the reference semantics) or `fixed` (the firmware's fixed point,
    /// the fixed-point interpreter's bits).
    #[arg(long, value_enum, default_value = "f64")]
    pub numeric: crate::values::Numeric,
    /// Engine: `jit` (cranelift, bit-identical to the interpreter of the same numeric, and
    /// many times faster) or `interp` (the interpreters that define the semantics).
    #[arg(long, value_enum, default_value = "jit")]
    pub engine: crate::values::EngineKind,
    /// Directory for the force–travel loop (`NAME-loop.svg`, `NAME-loop.csv`) and the
    /// dynamic sheet (`NAME-travel.svg`, `NAME-keybottom.svg`, `NAME-touches.csv`).
    #[arg(long, short, default_value = "out")]
    pub out: PathBuf,
}

fn figures_help() -> String {
    let mut s = String::from(
        "Measured as a piano technician measures an action, on the instrument's own semantics with\n\
         the closed-loop key model (a 30 g key and finger at the key front, pushed by weights laid\n\
         on gently or by a finger, the instrument's force pushing back, one sample of delay as on\n\
         the board). The first sensor is the key travel (0 at rest, its upper bound the key bed);\n\
         a hammer action publishes `hammer_pos` and emits `strike`. Figures that do not apply are\n\
         left out with a note. A sprung key's friction and balance weight come from its\n\
         quasi-static loop (its down- and up-weight are read at different travels).\n\
         The dynamic sheet (after `repetition`): a sweep of pressed touches (a 20 g finger on a\n\
         10 g key pushing 0.4–50 N) and struck ones (the finger hitting the key at 0.05–3 m/s,\n\
         then pushing), each timed from the finger's contact (as `tactus sim --touch` plays\n\
         them), read against the published measurements of grand actions (Goebl, Bresin and\n\
         Galembo 2005; Askenfelt and Jansson 1990). Figures (name in a spec file, unit):\n",
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
         \x20         tactus regulate grand_piano --spec instruments/specs/concert_grand.toml --spec instruments/specs/concert_grand_dynamic.toml\n\
         \x20         tactus regulate grand_piano --param M_h=11 g     # grand88's bass hammer\n\
         \x20         tactus regulate --layout grand88 --key 108       # C8 of grand88, as the keyboard compiles it\n\
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
    // The specs first: a mistake in one fails before the measuring.
    let specs = args
        .spec
        .iter()
        .map(|p| spec::read(p))
        .collect::<Result<Vec<_>, _>>()?;
    let (file, params) = match (&args.layout, args.key) {
        (Some(layout), Some(key)) => {
            let k = tactus_host::keyboard::layout_key(layout, key)?;
            let params = tactus_host::keyboard::with_overrides(&k.params, &args.params);
            let shown: Vec<String> = params.iter().map(|(n, v)| format!("{n}={v}")).collect();
            println!(
                "key {key} of {layout}: {} ({})",
                k.instrument,
                if shown.is_empty() {
                    "its own params".to_string()
                } else {
                    shown.join(", ")
                }
            );
            (k.instrument, params)
        }
        _ => (
            args.file
                .clone()
                .unwrap_or_else(|| "grand_piano".to_string()),
            args.params.clone(),
        ),
    };
    let src = source::load(&file)?;
    let Some(lowered) = compile_reporting(&src, &params, tactus_runtime::DEFAULT_SAMPLE_RATE_HZ)
    else {
        return Ok(ExitCode::from(2));
    };
    let config = Config {
        dynamic: !args.no_dynamic,
        ..Config::default()
    };
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
    let verdicts: Vec<Vec<spec::Verdict>> = specs.iter().map(|s| spec::check(&sheet, s)).collect();
    let all: Vec<spec::Verdict> = verdicts.iter().flatten().cloned().collect();
    print!(
        "{}",
        host_regulate::sheet_text(&sheet, (!specs.is_empty()).then_some(&all[..]))
    );
    let (svg, csv) = host_regulate::write_loop(&sheet, &args.out)?;
    println!("  wrote {} (force–travel loop)", svg.display());
    println!("  wrote {}", csv.display());
    for path in host_regulate::write_dynamic(&sheet, &args.out)? {
        println!("  wrote {}", path.display());
    }
    let mut holds = true;
    for (spec, verdicts) in specs.iter().zip(&verdicts) {
        let (ok, line) = host_regulate::spec_line(spec, verdicts);
        println!("{line}");
        holds &= ok;
    }
    Ok(if holds {
        ExitCode::SUCCESS
    } else {
        ExitCode::FAILURE
    })
}
