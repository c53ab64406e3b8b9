//! `tactus sim`: run an instrument over a stimulus (a key stimulus, a multi-sensor CSV or a
//! pen gesture; `tactus_compiler::sim::resolve`) on the host and write a CSV trace and SVG
//! plots.

use crate::check_cmd::{compile_reporting, parse_override};
use crate::{plot, source};
use std::path::PathBuf;
use std::process::ExitCode;
use tactus_runtime::stimulus;

/// Arguments of `tactus sim`.
#[derive(Debug, clap::Args)]
#[command(after_long_help = stimulus_help())]
pub struct SimArgs {
    /// Instrument file or built-in name (grand_piano, harpsichord, harpsichord_2x8, hammond,
    /// rubbed_bank).
    #[arg(default_value = "grand_piano")]
    pub file: String,
    /// Built-in key stimulus or pen gesture, or a CSV file (key positions, or one column
    /// per sensor; see below).
    #[arg(long, short, default_value = "ff-dip")]
    pub stimulus: String,
    /// Full key dip of the built-in key stimuli, mm [default: the key sensor's upper bound].
    #[arg(long, value_name = "MM")]
    pub dip: Option<f64>,
    /// Pen gestures: penetration while pressed, mm, as a reading of the depth sensor (a
    /// vector sensor's z, or sensor 1) [default: the middle of its range].
    #[arg(long, value_name = "MM", allow_negative_numbers = true)]
    pub depth: Option<f64>,
    /// Pen gestures: peak speed along the stroke axis (x, or sensor 2), m/s [default: 0.1;
    /// pluck 0.2].
    #[arg(long, value_name = "M_PER_S", allow_negative_numbers = true)]
    pub speed: Option<f64>,
    /// Pen gestures: stroke length along the stroke axis, mm [default: 20; bow-stroke 60 % of the
    /// range].
    #[arg(long, value_name = "MM", allow_negative_numbers = true)]
    pub stroke: Option<f64>,
    /// Pen gestures: reading of the sensor across the stroke (y, or sensor 3; e.g. which
    /// string), mm [default: its
    /// lower bound].
    #[arg(long, value_name = "MM", allow_negative_numbers = true)]
    pub across: Option<f64>,
    /// Also plot these trace columns (outputs, states, forces, sensors) against time into
    /// OUT/NAME-STIMULUS-plot.svg, one SVG with all of them (repeatable: `--plot vrel --plot
    /// friction`).
    #[arg(long = "plot", value_name = "NAME")]
    pub plots: Vec<String>,
    /// Override a param: `--param G=0.2 N` (repeatable).
    #[arg(long = "param", value_name = "NAME=VALUE", value_parser = parse_override)]
    pub params: Vec<(String, String)>,
    /// Arithmetic: `f64` (the reference semantics) or `fixed` (32-bit fixed point, the bits
    /// the firmware computes).
    #[arg(long, value_enum, default_value = "f64")]
    pub numeric: Numeric,
    /// Engine: `interp` (the interpreters that define the semantics) or `jit` (cranelift,
    /// native code on this machine, bit-identical to the interpreter of the same numeric).
    #[arg(long, value_enum, default_value = "interp")]
    pub engine: EngineKind,
    /// Directory for the trace and plots (created if missing).
    #[arg(long, short, default_value = "out")]
    pub out: PathBuf,
    /// Also write a WAV file: the instrument's outputs named `audio*` (or those chosen with
    /// `--wav-output`) summed into one 16-bit mono channel at the program's sample rate,
    /// normalised to 90 % of full scale.
    #[arg(long, value_name = "FILE")]
    pub wav: Option<PathBuf>,
    /// An output to write to the WAV instead of the `audio*` outputs (repeatable; summed).
    #[arg(long = "wav-output", value_name = "NAME", requires = "wav")]
    pub wav_outputs: Vec<String>,
}

/// Arithmetic of `tactus sim`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum Numeric {
    /// Double precision, the reference semantics.
    F64,
    /// 32-bit fixed point with the compiler's formats.
    Fixed,
}

/// Engine of `tactus sim`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum EngineKind {
    /// The reference interpreters.
    Interp,
    /// Cranelift JIT.
    Jit,
}

use tactus_host::sim as host_sim;

fn stimulus_help() -> String {
    let mut s = String::from(
        "Built-in key stimuli (key travel at the front, position-driven, first sensor only;\n\
         the other sensors read their lower bound):\n",
    );
    for (n, d) in stimulus::builtin_names() {
        s.push_str(&format!("  {n:<10} {d}\n"));
    }
    s.push_str(
        "\nPen gestures, for contact-point instruments (a vector sensor `pen: m in { z: …,\n\
         x: …, y: … }`: z = penetration, x = position along the stroke, optional y =\n\
         position across; without one, sensors 1, 2 and 3; --depth MM, --speed M_PER_S,\n\
         --stroke MM, --across MM; smooth ramps, clamped to the ranges):\n",
    );
    for (n, d) in tactus_compiler::sim::gesture_names() {
        s.push_str(&format!("  {n:<10} {d}\n"));
    }
    s.push_str(
        "\nA CSV stimulus has a header `key_mm` (one row per sample at 44.1 kHz) or\n\
         `time_s,key_mm` (any increasing times, linearly interpolated): key travel in mm,\n\
         first sensor. Or one column per sensor, named as in the trace: an optional first\n\
         column `time [s]`, then e.g. `pen.z [m],pen.x [m]`, values in SI units (metres, not\n\
         mm); sensors without a column read their lower bound, values outside a range are\n\
         clamped (with a warning).\n\n\
         Outputs: OUT/NAME-STIMULUS.csv (every force term, total — force.x, force.y,\n\
         force.z for a pen instrument —, states, modes, outputs, events), OUT/NAME-STIMULUS-forces.svg (force vs time, force vs key position), when\n\
         the instrument has outputs OUT/NAME-STIMULUS-outputs.svg, and with --plot\n\
         OUT/NAME-STIMULUS-plot.svg.\n\n\
         Examples: tactus sim instruments/grand_piano.tactus --stimulus half-dip --param G=0.2 N\n\
         \x20         tactus sim rubbed_bank --stimulus press-rub --depth 5 --speed 0.1 --plot force.x",
    );
    s
}

/// The pen gestures' names, comma-separated.
fn gesture_list() -> String {
    tactus_compiler::sim::gesture_names()
        .iter()
        .map(|(n, _)| *n)
        .collect::<Vec<_>>()
        .join(", ")
}

/// Writes the trace columns `names` against time into one SVG: one panel with every series
/// when they share a unit (y label `a, b [unit]`, display units: m as mm), otherwise (or
/// with an event column) one panel per column, each labelled with its unit.
fn plot_named(
    trace: &tactus_runtime::trace::Trace,
    names: &[String],
    title: &str,
    path: &std::path::Path,
) -> Result<(), String> {
    use tactus_runtime::trace::ColumnKind;
    let mut columns = Vec::with_capacity(names.len());
    for name in names {
        let c = trace
            .column(name)
            .ok_or_else(|| format!("--plot: no column `{name}` in the trace"))?;
        columns.push(c);
    }
    let unit = &columns[0].unit;
    let shared = columns
        .iter()
        .all(|c| &c.unit == unit && c.kind != ColumnKind::Event);
    if !shared {
        let refs: Vec<&str> = names.iter().map(String::as_str).collect();
        return plot::plot_columns(trace, &refs, title, path).map_err(|e| e.to_string());
    }
    let (scale, shown) = plot::display_unit(unit);
    let time_ms: Vec<f64> = trace.times_s().iter().map(|t| t * 1e3).collect();
    let lines: Vec<plot::Line> = columns
        .iter()
        .map(|c| plot::Line {
            label: c.name.clone(),
            x: time_ms.clone(),
            y: c.values.iter().map(|v| v * scale).collect(),
        })
        .collect();
    let joined = names.join(", ");
    let y_desc = if shown.is_empty() {
        joined
    } else {
        format!("{joined} [{shown}]")
    };
    plot::plot_lines(&lines, title, "time [ms]", &y_desc, path).map_err(|e| e.to_string())
}

/// Runs `tactus sim`.
pub fn run(args: SimArgs) -> ExitCode {
    match run_inner(&args) {
        Ok(code) => code,
        Err(e) => {
            eprintln!("error: {e}");
            ExitCode::FAILURE
        }
    }
}

fn run_inner(args: &SimArgs) -> Result<ExitCode, String> {
    let src = source::load(&args.file)?;
    let Some(lowered) =
        compile_reporting(&src, &args.params, tactus_runtime::DEFAULT_SAMPLE_RATE_HZ)
    else {
        return Ok(ExitCode::FAILURE);
    };
    let program = &lowered.program;
    let fs = program.sample_rate_hz;
    let word = args.stimulus.as_str();
    let is_file = std::path::Path::new(word).is_file();
    let gesture = !is_file && tactus_compiler::sim::is_gesture(word);
    let pen_options = [
        ("--depth", args.depth),
        ("--speed", args.speed),
        ("--stroke", args.stroke),
        ("--across", args.across),
    ];
    if !gesture {
        if let Some((flag, _)) = pen_options.iter().find(|(_, v)| v.is_some()) {
            return Err(format!(
                "{flag} applies to the pen gestures ({}), not to `{word}`",
                gesture_list()
            ));
        }
    }
    if args.dip.is_some() && (gesture || is_file) {
        return Err(format!(
            "--dip applies to the built-in key stimuli, not to `{word}`{}",
            if gesture { " (use --depth)" } else { "" }
        ));
    }
    let run = host_sim::simulate(
        program,
        &host_sim::SimRequest {
            stimulus: word,
            dip_m: args.dip.map(|mm| mm * 1e-3),
            gesture: tactus_compiler::sim::GestureConfig {
                depth_m: args.depth.map(|mm| mm * 1e-3),
                speed_m_per_s: args.speed,
                stroke_m: args.stroke.map(|mm| mm * 1e-3),
                across_m: args.across.map(|mm| mm * 1e-3),
            },
            numeric: match args.numeric {
                Numeric::F64 => host_sim::Numeric::F64,
                Numeric::Fixed => host_sim::Numeric::Fixed,
            },
            engine: match args.engine {
                EngineKind::Interp => host_sim::Engine::Interp,
                EngineKind::Jit => host_sim::Engine::Jit,
            },
            plots: &args.plots,
            wav: args.wav.as_ref().map(|_| args.wav_outputs.as_slice()),
        },
    )?;
    for note in &run.notes {
        eprintln!("warning: {note}");
    }
    crate::source::report(&src, &run.fixed_warnings);
    let (trace, summary, stem) = (&run.trace, &run.summary, &run.stem);
    std::fs::create_dir_all(&args.out)
        .map_err(|e| format!("cannot create `{}`: {e}", args.out.display()))?;
    let csv = args.out.join(format!("{stem}.csv"));
    trace.write_csv_file(&csv).map_err(|e| e.to_string())?;
    let title = format!("{} — {}", program.name, run.stimulus);
    // A NaN or ∞ means the run lost the program's meaning (the fixed engines saturate, so
    // this is the f64 engines'): keep the CSV to look at, plot nothing, fail.
    if let Some((column, n, v)) = tactus_compiler::sim::first_non_finite(trace) {
        return Err(format!(
            "{title}: `{column}` is {v} at sample {n} (t = {:.6} s): the simulation computed a non-finite value (a division by zero, an overflow or an unstable scheme); the trace up to there is in {}",
            n as f64 / fs,
            csv.display(),
        ));
    }
    let forces_svg = args.out.join(format!("{stem}-forces.svg"));
    plot::plot_forces(trace, &title, &forces_svg).map_err(|e| e.to_string())?;
    let mut written = vec![csv, forces_svg];
    if let (Some(wav), Some(names)) = (&args.wav, &run.wav_outputs) {
        host_sim::write_wav(trace, names, fs, wav)?;
        written.push(wav.clone());
    }
    if !program.outputs.is_empty() {
        let names: Vec<&str> = program.outputs.iter().map(|o| o.name.as_str()).collect();
        let svg = args.out.join(format!("{stem}-outputs.svg"));
        plot::plot_columns(trace, &names, &title, &svg).map_err(|e| e.to_string())?;
        written.push(svg);
    }
    if !args.plots.is_empty() {
        let svg = args.out.join(format!("{stem}-plot.svg"));
        plot_named(trace, &args.plots, &title, &svg)?;
        written.push(svg);
    }

    // The total force's range: one for a keyboard, one per axis for a pen instrument.
    let totals: Vec<String> = host_sim::force_ranges(program, trace)
        .into_iter()
        .map(|(name, lo, hi)| {
            let what = if name == "total" { "total force" } else { name };
            format!("{what} {lo:.3} N … {hi:.3} N")
        })
        .collect();
    println!(
        "{}: {} samples ({:.3} s at {} Hz), {}",
        title,
        run.samples,
        run.duration_s,
        fs,
        totals.join(", ")
    );
    for (n, name, a) in &summary.events {
        let ev = program.events.iter().find(|e| &e.name == name);
        let args_text: Vec<String> = ev
            .map(|e| {
                e.args
                    .iter()
                    .zip(a)
                    .map(|((an, d), v)| format!("{an} = {v:.4} {}", d.unit_string()))
                    .collect()
            })
            .unwrap_or_default();
        println!(
            "  event {name} at {:.2} ms: {}",
            *n as f64 / fs * 1e3,
            args_text.join(", ")
        );
    }
    for (s, &count) in program.states.iter().zip(&summary.saturations) {
        if count > 0 {
            eprintln!(
                "warning: state `{}` was saturated to its range [{}, {}] {} {count} times; widen the range if this is not intended",
                s.name, s.range.0, s.range.1, s.dim.unit_string()
            );
        }
    }
    for w in written {
        println!("  wrote {}", w.display());
    }
    Ok(ExitCode::SUCCESS)
}
