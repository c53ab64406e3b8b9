//! `tactus regulate`: the regulation sheet of a key instrument
//! (`tactus_firmware::regulate::measure`), printed as a technician's table, the
//! force–travel loop plotted, and with `--spec` a verdict per figure.

use crate::check_cmd::{compile_reporting, parse_override};
use crate::{plot, source};
use std::path::PathBuf;
use std::process::ExitCode;
use tactus_firmware::regulate::{self, spec, Config, Figure, Sheet};

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
    pub numeric: crate::sim_cmd::Numeric,
    /// Engine: `jit` (cranelift, bit-identical to the interpreter of the same numeric, and
    /// many times faster) or `interp` (the interpreters that define the semantics).
    #[arg(long, value_enum, default_value = "jit")]
    pub engine: crate::sim_cmd::EngineKind,
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
    let program = &lowered.program;
    let config = Config::default();
    use crate::sim_cmd::{EngineKind, Numeric};
    use tactus_firmware::play::engine::{FixedJitEngine, JitEngine};
    let sheet = match (args.numeric, args.engine) {
        (Numeric::F64, EngineKind::Interp) => regulate::measure(
            program,
            tactus_compiler::interp::Instance::new(program),
            &config,
        )?,
        (Numeric::F64, EngineKind::Jit) => {
            let jit = tactus_jit::JitProgram::compile(program).map_err(|e| format!("JIT: {e}"))?;
            regulate::measure(
                program,
                JitEngine(tactus_jit::JitInstance::new(&jit)),
                &config,
            )?
        }
        (Numeric::Fixed, engine) => {
            let fp = tactus_compiler::fixed::FixedProgram::new(program);
            source::report(&src, &fp.warnings);
            if engine == EngineKind::Jit {
                let jit = tactus_jit::fixed::FixedJitProgram::compile(&fp)
                    .map_err(|e| format!("JIT: {e}"))?;
                regulate::measure(
                    program,
                    FixedJitEngine(tactus_jit::fixed::FixedJitInstance::new(&jit), &fp),
                    &config,
                )?
            } else {
                regulate::measure(
                    program,
                    tactus_compiler::fixed::interp::FixedInstance::new(&fp),
                    &config,
                )?
            }
        }
    };
    let numeric = match args.numeric {
        crate::sim_cmd::Numeric::F64 => "f64 semantics",
        crate::sim_cmd::Numeric::Fixed => "fixed point",
    };
    println!(
        "{} — regulation sheet ({numeric}; closed-loop key of {:.0} g at the key front)",
        sheet.instrument,
        config.finger.mass_kg * 1e3
    );
    let verdicts = spec.as_ref().map(|s| spec::check(&sheet, s));
    print_sheet(&sheet, verdicts.as_deref());
    let (svg, csv) = write_loop(&sheet, &args.out)?;
    println!("  wrote {} (force–travel loop)", svg.display());
    println!("  wrote {}", csv.display());
    let Some(verdicts) = verdicts else {
        return Ok(ExitCode::SUCCESS);
    };
    let spec = spec.expect("verdicts come from a spec");
    let failed: Vec<&spec::Verdict> = verdicts.iter().filter(|v| !v.holds()).collect();
    if failed.is_empty() {
        println!(
            "within spec `{}`: all {} figures in range",
            spec.name,
            verdicts.len()
        );
        Ok(ExitCode::SUCCESS)
    } else {
        println!(
            "OUTSIDE spec `{}`: {} of {} figures ({})",
            spec.name,
            failed.len(),
            verdicts.len(),
            failed
                .iter()
                .map(|v| v.range.figure.key())
                .collect::<Vec<_>>()
                .join(", ")
        );
        Ok(ExitCode::FAILURE)
    }
}

/// Prints the sheet: one line per figure (value, unit, the spec's range and verdict when
/// given, how it was measured), then the spec's figures not measured, then the notes.
fn print_sheet(sheet: &Sheet, verdicts: Option<&[spec::Verdict]>) {
    let range_of = |f: Figure| verdicts.and_then(|v| v.iter().find(|v| v.range.figure == f));
    println!(
        "  {:<26} {:>9} {:<8} {:<14} how it was measured",
        "figure",
        "value",
        "unit",
        if verdicts.is_some() { "spec" } else { "" }
    );
    for m in &sheet.figures {
        let (range, verdict) = match range_of(m.figure) {
            Some(v) => (v.range.text(), if v.holds() { "ok  " } else { "OUT " }),
            None => (String::new(), "    "),
        };
        println!(
            "  {:<26} {:>9} {:<8} {:<14} {verdict}{}",
            m.figure.title(),
            format!("{:.2}", m.value),
            m.figure.unit(),
            range,
            m.how
        );
    }
    if let Some(verdicts) = verdicts {
        for v in verdicts.iter().filter(|v| v.value.is_none()) {
            println!(
                "  {:<26} {:>9} {:<8} {:<14} OUT not measured",
                v.range.figure.title(),
                "—",
                v.range.figure.unit(),
                v.range.text()
            );
        }
    }
    for n in &sheet.notes {
        println!("  note: {n}");
    }
}

/// Writes the loop as `OUT/NAME-loop.svg` (force in gf against travel in mm, down and up
/// in two colours) and `OUT/NAME-loop.csv` (the binned means).
fn write_loop(sheet: &Sheet, out: &std::path::Path) -> Result<(PathBuf, PathBuf), String> {
    std::fs::create_dir_all(out).map_err(|e| format!("cannot create `{}`: {e}", out.display()))?;
    let lp = &sheet.force_loop;
    let line = |label: &str, pts: &[(f64, f64)]| plot::Line {
        label: label.to_string(),
        x: pts.iter().map(|p| p.0 * 1e3).collect(),
        y: pts.iter().map(|p| regulate::n_to_gf(p.1)).collect(),
    };
    let svg = out.join(format!("{}-loop.svg", sheet.instrument));
    plot::plot_lines(
        &[line("going down", &lp.down), line("going up", &lp.up)],
        &format!(
            "{}: force at the key on a quasi-static dip ({} mm/s)",
            sheet.instrument,
            regulate::QUASI_STATIC_SPEED * 1e3
        ),
        "key travel [mm]",
        "force at the key [gf]",
        &svg,
    )
    .map_err(|e| e.to_string())?;
    let csv = out.join(format!("{}-loop.csv", sheet.instrument));
    let mut text = String::from("travel [mm],down [gf],up [gf]\n");
    for (i, (d, u)) in lp.down_bins.iter().zip(&lp.up_bins).enumerate() {
        let cell = |v: &Option<f64>| {
            v.map(|f| format!("{:.3}", regulate::n_to_gf(f)))
                .unwrap_or_default()
        };
        text.push_str(&format!(
            "{:.3},{},{}\n",
            (i as f64 + 0.5) * lp.bin_m * 1e3,
            cell(d),
            cell(u)
        ));
    }
    std::fs::write(&csv, text).map_err(|e| format!("{}: cannot write: {e}", csv.display()))?;
    Ok((svg, csv))
}
