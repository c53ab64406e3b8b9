//! One instrument over a stimulus on the host, as `tactus sim` runs it: the stimulus
//! resolved for the program (`tactus_compiler::sim::resolve`: a built-in key stimulus, a
//! pen gesture or a CSV file), the requested trace columns and WAV outputs checked before
//! anything runs, the trace bounded, and the run on the chosen arithmetic and engine. The
//! caller writes the CSV and the plots, and prints.

use tactus_compiler::diagnostics::Diagnostic;
use tactus_compiler::ir::{Program, Ty};
use tactus_compiler::sim::{GestureConfig, SimSummary};
use tactus_firmware::play::engine::{FixedJitEngine, JitEngine};
use tactus_runtime::trace::{ColumnKind, Trace};

/// The arithmetic of a run.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Numeric {
    /// Double precision, the reference semantics.
    F64,
    /// 32-bit fixed point with the compiler's formats: the firmware's bits.
    Fixed,
}

/// The engine of a run: both give the same bits for one arithmetic.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Engine {
    /// The interpreters that define the semantics.
    Interp,
    /// Cranelift, native code on this machine.
    Jit,
}

/// What to run.
#[derive(Clone, Debug)]
pub struct SimRequest<'a> {
    /// A built-in key stimulus or pen gesture, or a CSV file.
    pub stimulus: &'a str,
    /// The full key dip of a built-in key stimulus, m (`None`: the key sensor's range).
    pub dip_m: Option<f64>,
    /// A pen gesture's depth, speed, stroke and position across.
    pub gesture: GestureConfig,
    /// The arithmetic.
    pub numeric: Numeric,
    /// The engine.
    pub engine: Engine,
    /// Trace columns to plot besides the defaults: each must be a column of the trace.
    pub plots: &'a [String],
    /// `Some` when a WAV is asked for: the outputs chosen (empty: every `audio*` output).
    pub wav: Option<&'a [String]>,
}

/// A run: the trace and what happened in it.
#[derive(Clone, Debug)]
pub struct SimRun {
    /// The stimulus's name (a CSV's file name).
    pub stimulus: String,
    /// Its samples.
    pub samples: usize,
    /// Its duration, s.
    pub duration_s: f64,
    /// Remarks on the stimulus (e.g. a CSV's columns mapped to sensors), to show as
    /// warnings.
    pub notes: Vec<String>,
    /// The fixed-point plan's warnings (with [`Numeric::Fixed`]).
    pub fixed_warnings: Vec<Diagnostic>,
    /// The trace: time, sensors, states, forces, outputs, one row per sample, SI.
    pub trace: Trace,
    /// Events and saturations.
    pub summary: SimSummary,
    /// The outputs the WAV sums, when one is asked for.
    pub wav_outputs: Option<Vec<String>>,
    /// `INSTRUMENT-STIMULUS` and a suffix for the arithmetic and engine: the files' stem.
    pub stem: String,
}

/// Runs `program` as `req` says.
///
/// Errors, as messages: the program has no sensor; a WAV output or plotted column that
/// does not exist (naming the ones that do); a stimulus that does not resolve; a trace
/// longer than `tactus_compiler::sim::MAX_TRACE_VALUES`; a JIT that does not compile.
pub fn simulate(program: &Program, req: &SimRequest) -> Result<SimRun, String> {
    if program.sensors.is_empty() {
        return Err(format!(
            "instrument `{}` has no sensor to drive",
            program.name
        ));
    }
    // Checked before the simulation, so that a misspelt output fails at once.
    let wav_outputs = req
        .wav
        .map(|chosen| wav_outputs(program, chosen))
        .transpose()?;
    let columns = tactus_compiler::sim::trace_columns(program);
    for name in req.plots {
        if name == "time" || columns.column(name).is_none() {
            let available: Vec<&str> = columns
                .columns
                .iter()
                .filter(|c| c.name != "time")
                .map(|c| c.name.as_str())
                .collect();
            return Err(format!(
                "--plot: `{name}` is not a column of the trace of `{}` (available: {})",
                program.name,
                available.join(", ")
            ));
        }
    }
    let fs = program.sample_rate_hz;
    let stim = tactus_compiler::sim::resolve(program, req.stimulus, req.dip_m, &req.gesture, fs)
        .map_err(|e| e.to_string())?;
    let values = tactus_compiler::sim::trace_values(program, stim.len());
    if values > tactus_compiler::sim::MAX_TRACE_VALUES {
        return Err(format!(
            "{}: {} samples × {} trace columns is {values} values, more than the {} a trace may hold; shorten the stimulus",
            stim.name,
            stim.len(),
            columns.columns.len(),
            tactus_compiler::sim::MAX_TRACE_VALUES
        ));
    }
    let mut fixed_warnings = Vec::new();
    let (trace, summary) = match (req.numeric, req.engine) {
        (Numeric::F64, Engine::Interp) => tactus_compiler::sim::simulate_sensors(program, &stim),
        (Numeric::F64, Engine::Jit) => {
            let jit = tactus_jit::JitProgram::compile(program).map_err(|e| format!("JIT: {e}"))?;
            let mut engine = JitEngine(tactus_jit::JitInstance::new(&jit));
            tactus_compiler::sim::simulate_sensors_with(program, &mut engine, &stim)
        }
        (Numeric::Fixed, engine) => {
            let fp = tactus_compiler::fixed::FixedProgram::new(program);
            fixed_warnings = fp.warnings.clone();
            if engine == Engine::Jit {
                let jit = tactus_jit::fixed::FixedJitProgram::compile(&fp)
                    .map_err(|e| format!("JIT: {e}"))?;
                let mut engine =
                    FixedJitEngine(tactus_jit::fixed::FixedJitInstance::new(&jit), &fp);
                tactus_compiler::sim::simulate_sensors_with(program, &mut engine, &stim)
            } else {
                let mut inst = tactus_compiler::fixed::interp::FixedInstance::new(&fp);
                tactus_compiler::sim::simulate_sensors_with(program, &mut inst, &stim)
            }
        }
    };
    let suffix = match (req.numeric, req.engine) {
        (Numeric::Fixed, Engine::Interp) => "-fixed",
        (Numeric::Fixed, Engine::Jit) => "-fixed-jit",
        (Numeric::F64, Engine::Jit) => "-jit",
        (Numeric::F64, Engine::Interp) => "",
    };
    Ok(SimRun {
        stem: format!(
            "{}-{}{suffix}",
            program.name,
            stim.name.trim_end_matches(".csv")
        ),
        stimulus: stim.name.clone(),
        samples: stim.len(),
        duration_s: stim.duration_s(),
        notes: stim.notes.iter().map(|n| n.to_string()).collect(),
        fixed_warnings,
        trace,
        summary,
        wav_outputs,
    })
}

/// Per total force (one for a keyboard program, one per axis for a pen): its name and the
/// range it spans in `trace`, N.
pub fn force_ranges(program: &Program, trace: &Trace) -> Vec<(&'static str, f64, f64)> {
    let names: &[&'static str] = if program.is_pen() {
        &["force.x", "force.y", "force.z"]
    } else {
        &["total"]
    };
    names
        .iter()
        .map(|&name| {
            let (mut lo, mut hi) = (f64::INFINITY, f64::NEG_INFINITY);
            for &f in trace.column(name).map_or(&[][..], |c| &c.values[..]) {
                lo = lo.min(f);
                hi = hi.max(f);
            }
            (name, lo, hi)
        })
        .collect()
}

/// The outputs `--wav` writes: `chosen` (each must be a numeric output of `program`), or
/// else every output whose name starts with `audio`, in declaration order.
pub fn wav_outputs(
    program: &tactus_compiler::ir::Program,
    chosen: &[String],
) -> Result<Vec<String>, String> {
    let numeric: Vec<&str> = program
        .outputs
        .iter()
        .filter(|o| matches!(o.ty, Ty::Real(_)))
        .map(|o| o.name.as_str())
        .collect();
    if chosen.is_empty() {
        let audio: Vec<String> = numeric
            .iter()
            .filter(|n| n.starts_with("audio"))
            .map(|n| n.to_string())
            .collect();
        if audio.is_empty() {
            return Err(format!(
                "--wav: instrument `{}` has no output named `audio*`; choose one with --wav-output NAME (outputs: {})",
                program.name,
                if numeric.is_empty() { "none".to_string() } else { numeric.join(", ") }
            ));
        }
        return Ok(audio);
    }
    for c in chosen {
        if !numeric.contains(&c.as_str()) {
            return Err(format!(
                "--wav-output: `{c}` is not a numeric output of `{}` (outputs: {})",
                program.name,
                if numeric.is_empty() {
                    "none".to_string()
                } else {
                    numeric.join(", ")
                }
            ));
        }
    }
    Ok(chosen.to_vec())
}

/// Writes the sum of the trace's output columns `names` (SI, one per sample) as a 16-bit
/// mono WAV at `fs` Hz, with its peak at 90 % of full scale (silence stays silence).
///
/// Errors: a name that is not an output column of the trace, `fs` not a whole number of
/// hertz, or the file cannot be written (naming it).
pub fn write_wav(
    trace: &tactus_runtime::trace::Trace,
    names: &[String],
    fs: f64,
    path: &std::path::Path,
) -> Result<(), String> {
    let mut mix = vec![0f32; trace.len()];
    for name in names {
        let col = trace
            .columns_of(ColumnKind::Output)
            .find(|c| &c.name == name)
            .ok_or_else(|| format!("--wav: no output column `{name}` in the trace"))?;
        for (m, &x) in mix.iter_mut().zip(&col.values) {
            *m += x as f32;
        }
    }
    tactus_firmware::play::output::write_mono_wav(path, &mix, fs).map_err(|e| format!("--wav: {e}"))
}
