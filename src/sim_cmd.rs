//! `tactus sim`: run an instrument over a stimulus (a key stimulus, a multi-sensor CSV or a
//! pen gesture; `tactus_compiler::sim::resolve`) on the host and write a CSV trace and SVG
//! plots.

use crate::check_cmd::{compile_reporting, parse_override};
use crate::source;
use std::path::PathBuf;
use std::process::ExitCode;

/// Arguments of `tactus sim`.
#[derive(Debug, clap::Args)]
#[command(after_long_help = host_sim::stimulus_help())]
pub struct SimArgs {
    /// Instrument file or built-in name (grand_piano, harpsichord, harpsichord_2x8, hammond,
    /// rubbed_bank).
    #[arg(default_value = "grand_piano")]
    pub file: String,
    /// Built-in key stimulus or pen gesture, or a CSV file (key positions, or one column
    /// per sensor; see below).
    #[arg(long, short, default_value = "ff-dip")]
    pub stimulus: String,
    /// A pianist's touch instead of a stimulus: the key moved by a finger against the
    /// instrument's force (closed loop). `pressed:FORCE` (the finger on the key pushes, e.g.
    /// `pressed:8N`), `struck:SPEED` (the finger hits the key at a speed, then pushes, e.g.
    /// `struck:2.5m/s`), or a level: `pressed:pp` … `struck:fff`.
    #[arg(long, value_name = "TOUCH", value_parser = tactus_runtime::player::Touch::parse, conflicts_with = "stimulus")]
    pub touch: Option<tactus_runtime::player::Touch>,
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
    pub numeric: crate::values::Numeric,
    /// Engine: `interp` (the interpreters that define the semantics) or `jit` (cranelift,
    /// native code on this machine, bit-identical to the interpreter of the same numeric).
    #[arg(long, value_enum, default_value = "interp")]
    pub engine: crate::values::EngineKind,
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

use tactus_host::sim as host_sim;

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
    let mm = |v: Option<f64>| v.map(|mm| mm * 1e-3);
    let run = host_sim::simulate(
        program,
        &host_sim::SimRequest {
            stimulus: &args.stimulus,
            dip_m: mm(args.dip),
            gesture: tactus_compiler::sim::GestureConfig {
                depth_m: mm(args.depth),
                speed_m_per_s: args.speed,
                stroke_m: mm(args.stroke),
                across_m: mm(args.across),
            },
            numeric: args.numeric.into(),
            engine: args.engine.into(),
            plots: &args.plots,
            wav: args.wav.as_ref().map(|_| args.wav_outputs.as_slice()),
            touch: args.touch,
        },
    )?;
    for note in &run.notes {
        eprintln!("warning: {note}");
    }
    source::report(&src, &run.fixed_warnings);
    let written =
        host_sim::write_files(program, &run, &args.plots, &args.out, args.wav.as_deref())?;
    let (lines, warnings) = host_sim::report(program, &run);
    for line in lines {
        println!("{line}");
    }
    for w in warnings {
        eprintln!("warning: {w}");
    }
    for w in written {
        println!("  wrote {}", w.display());
    }
    Ok(ExitCode::SUCCESS)
}
