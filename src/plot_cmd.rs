//! `tactus plot`: plots of the models behind the instruments, independent of any
//! instrument file.
//!
//! `tactus plot friction` draws Bilbao's friction characteristic
//! `φ(v, a) = √(2a)·v·exp(−a·v² + ½)` (Bilbao, *Numerical Sound Synthesis*, Wiley 2009, the
//! bow model) for several `a`, as in Fig. 9 of Onofrei, Fontana & Serafin 2023 (plucking,
//! bowing and rubbing physically-based resonators): the friction force is `F = N·φ(v_rel,
//! a)`, odd in `v`, with its extremes ±1 at `v = ±1/√(2a)`; small `a` is "slippery" (a
//! gentle slope over the whole range), large `a` "sticky" (a sharp peak near `v = 0`).

use std::path::{Path, PathBuf};
use std::process::ExitCode;
use tactus_host::plot;
use tactus_runtime::friction;

/// Subcommands of `tactus plot`.
#[derive(Debug, clap::Subcommand)]
pub enum PlotCommand {
    /// Bilbao's friction characteristic φ(v, a) = √(2a)·v·exp(−a·v² + ½) over
    /// v ∈ [−0.5, 0.5] m/s for several a (Onofrei et al. 2023, Fig. 9): an SVG and a CSV of
    /// the curves.
    Friction(FrictionArgs),
}

/// Arguments of `tactus plot friction`.
#[derive(Debug, clap::Args)]
pub struct FrictionArgs {
    /// Friction parameter a, s²/m² (repeatable) [default: 0.01, 1, 100, 15000, the range of
    /// Onofrei et al. 2023 from "slippery" to "sticky"].
    #[arg(long = "a", value_name = "S2_PER_M2", allow_negative_numbers = true)]
    pub a: Vec<f64>,
    /// The SVG to write; the curves also go to the same path with extension `.csv`
    /// (columns `v [m/s]`, then `phi(a=…)` per a).
    #[arg(long, short, default_value = "out/friction.svg")]
    pub out: PathBuf,
    /// Largest |v| plotted, m/s.
    #[arg(long, value_name = "M_PER_S", default_value_t = 0.5)]
    pub v_max: f64,
}

/// Runs `tactus plot`.
pub fn run(cmd: PlotCommand) -> ExitCode {
    let result = match cmd {
        PlotCommand::Friction(args) => friction(&args),
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {e}");
            ExitCode::FAILURE
        }
    }
}

fn friction(args: &FrictionArgs) -> Result<(), String> {
    let a_values: Vec<f64> = if args.a.is_empty() {
        friction::DEFAULT_A.to_vec()
    } else {
        args.a.clone()
    };
    for &a in &a_values {
        if !(a.is_finite() && a > 0.0) {
            return Err(format!("--a {a}: must be finite and > 0 (s²/m²)"));
        }
    }
    if !(args.v_max.is_finite() && args.v_max > 0.0) {
        return Err(format!(
            "--v-max {}: must be finite and > 0 (m/s)",
            args.v_max
        ));
    }
    let v = friction::velocities(&a_values, args.v_max);
    let lines: Vec<plot::Line> = a_values
        .iter()
        .map(|&a| plot::Line {
            label: format!("a = {a} s²/m²"),
            x: v.clone(),
            y: v.iter().map(|&x| friction::bilbao_phi(x, a)).collect(),
        })
        .collect();
    if let Some(dir) = args.out.parent().filter(|d| !d.as_os_str().is_empty()) {
        std::fs::create_dir_all(dir)
            .map_err(|e| format!("cannot create `{}`: {e}", dir.display()))?;
    }
    plot::plot_lines(
        &lines,
        "Bilbao's friction characteristic φ(v, a) = √(2a)·v·exp(−a·v² + ½)",
        "relative velocity v [m/s]",
        "φ(v, a)",
        &args.out,
    )
    .map_err(|e| e.to_string())?;
    let csv = args.out.with_extension("csv");
    write_csv(&csv, &v, &a_values, &lines)?;
    println!(
        "friction characteristic for a = {} s²/m² (extremes ±1 at v = ±1/√(2a): {} m/s)",
        a_values
            .iter()
            .map(f64::to_string)
            .collect::<Vec<_>>()
            .join(", "),
        a_values
            .iter()
            .map(|a| format!("{:.4}", 1.0 / (2.0 * a).sqrt()))
            .collect::<Vec<_>>()
            .join(", ")
    );
    println!("  wrote {}", args.out.display());
    println!("  wrote {}", csv.display());
    Ok(())
}

fn write_csv(path: &Path, v: &[f64], a_values: &[f64], lines: &[plot::Line]) -> Result<(), String> {
    use std::fmt::Write as _;
    let mut text = String::from("v [m/s]");
    for a in a_values {
        let _ = write!(text, ",phi(a={a})");
    }
    text.push('\n');
    for (i, x) in v.iter().enumerate() {
        let _ = write!(text, "{x}");
        for l in lines {
            let _ = write!(text, ",{}", l.y[i]);
        }
        text.push('\n');
    }
    std::fs::write(path, text).map_err(|e| format!("{}: cannot write: {e}", path.display()))
}
