//! `tactus plot`: plots of the models behind the instruments, independent of any
//! instrument file.
//!
//! `tactus plot friction` draws Bilbao's friction characteristic
//! `φ(v, a) = √(2a)·v·exp(−a·v² + ½)` (Bilbao, *Numerical Sound Synthesis*, Wiley 2009, the
//! bow model) for several `a`, as in Fig. 9 of Onofrei, Fontana & Serafin 2023 (plucking,
//! bowing and rubbing physically-based resonators): the friction force is `F = N·φ(v_rel,
//! a)`, odd in `v`, with its extremes ±1 at `v = ±1/√(2a)`; small `a` is "slippery" (a
//! gentle slope over the whole range), large `a` "sticky" (a sharp peak near `v = 0`).

use std::path::PathBuf;
use std::process::ExitCode;
use tactus_host::plot;

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
    let done = plot::plot_friction(&args.a, args.v_max, &args.out)?;
    let list =
        |f: &dyn Fn(&(f64, f64)) -> String| done.peaks.iter().map(f).collect::<Vec<_>>().join(", ");
    println!(
        "friction characteristic for a = {} s²/m² (extremes ±1 at v = ±1/√(2a): {} m/s)",
        list(&|(a, _)| a.to_string()),
        list(&|(_, v)| format!("{v:.4}")),
    );
    println!("  wrote {}", args.out.display());
    println!("  wrote {}", done.csv.display());
    Ok(())
}
