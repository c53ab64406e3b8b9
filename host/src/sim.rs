//! One instrument over a stimulus on the host, as `tactus sim` runs it: the stimulus
//! resolved for the program (`tactus_compiler::sim::resolve`: a built-in key stimulus, a
//! pen gesture or a CSV file), the requested trace columns and WAV outputs checked before
//! anything runs, the trace bounded, and the run on the chosen arithmetic and engine. The
//! caller writes the CSV and the plots, and prints.

use crate::play::engine::{FixedJitEngine, JitEngine};
use crate::plot;
use std::path::{Path, PathBuf};
use tactus_compiler::diagnostics::Diagnostic;
use tactus_compiler::ir::{Program, Ty};
use tactus_compiler::sim::{GestureConfig, SimSummary};
use tactus_runtime::player::{Fingertip, Touch, TouchPlay};
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
    /// A pianist's touch instead of the stimulus: the key moved by a finger against the
    /// instrument's force ([`TOUCH_LIFT_S`]; `tactus_runtime::player::TouchPlay`).
    pub touch: Option<Touch>,
}

/// When the finger of `tactus sim --touch` meets the key, s (after 20 ms at rest, as the
/// built-in stimuli start).
pub const TOUCH_START_S: f64 = 0.020;

/// When it lifts, s: after its push and 0.4 s of holding the key down with
/// [`TOUCH_HOLD_N`].
pub const TOUCH_LIFT_S: f64 = 0.6;

/// The force that holds the key down after the push, N (the force player's hold:
/// `tactus_runtime::player::FingerConfig::default`).
pub const TOUCH_HOLD_N: f64 = 1.2;

/// How long a touch run lasts, s: the lift and 0.4 s of the key rising and the action
/// settling.
pub const TOUCH_RUN_S: f64 = 1.0;

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
    /// `INSTRUMENT — STIMULUS`: the plots' title.
    pub title: String,
    /// `INSTRUMENT-STIMULUS` and a suffix for the arithmetic and engine: the files' stem.
    pub stem: String,
}

/// Runs `program` as `req` says.
///
/// Errors, as messages: the program has no sensor; a pen gesture's option (`gesture`) with
/// a stimulus that is not a pen gesture, or `dip_m` with one that is not a built-in key
/// stimulus; a touch on a pen instrument or on one whose first sensor is not a key travel
/// from 0; a WAV output or plotted column that
/// does not exist (naming the ones that do); a stimulus that does not resolve; a trace
/// longer than `tactus_compiler::sim::MAX_TRACE_VALUES`; a JIT that does not compile.
pub fn simulate(program: &Program, req: &SimRequest) -> Result<SimRun, String> {
    if program.sensors.is_empty() {
        return Err(format!(
            "instrument `{}` has no sensor to drive",
            program.name
        ));
    }
    if let Some(touch) = req.touch {
        return simulate_touch(program, req, touch);
    }
    // Options that apply to one kind of stimulus only: an error, not a silent no-op.
    let word = req.stimulus;
    let is_file = std::path::Path::new(word).is_file();
    let gesture = !is_file && tactus_compiler::sim::is_gesture(word);
    let g = &req.gesture;
    let pen_options = [
        ("--depth", g.depth_m),
        ("--speed", g.speed_m_per_s),
        ("--stroke", g.stroke_m),
        ("--across", g.across_m),
    ];
    if !gesture {
        if let Some((flag, _)) = pen_options.iter().find(|(_, v)| v.is_some()) {
            let names: Vec<&str> = tactus_compiler::sim::gesture_names()
                .iter()
                .map(|(n, _)| *n)
                .collect();
            return Err(format!(
                "{flag} applies to the pen gestures ({}), not to `{word}`",
                names.join(", ")
            ));
        }
    }
    if req.dip_m.is_some() && (gesture || is_file) {
        return Err(format!(
            "--dip applies to the built-in key stimuli, not to `{word}`{}",
            if gesture { " (use --depth)" } else { "" }
        ));
    }
    let (wav_outputs, columns) = check_outputs(program, req, &[])?;
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
    let ((trace, summary), fixed_warnings) =
        with_engine(program, req.numeric, req.engine, &mut |engine| {
            tactus_compiler::sim::simulate_sensors_with(program, engine, &stim)
        })?;
    Ok(SimRun {
        title: format!("{} — {}", program.name, stim.name),
        stem: format!(
            "{}-{}{}",
            program.name,
            stim.name.trim_end_matches(".csv"),
            suffix(req)
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

/// The file stem's suffix for the arithmetic and engine of `req`.
fn suffix(req: &SimRequest) -> &'static str {
    match (req.numeric, req.engine) {
        (Numeric::Fixed, Engine::Interp) => "-fixed",
        (Numeric::Fixed, Engine::Jit) => "-fixed-jit",
        (Numeric::F64, Engine::Jit) => "-jit",
        (Numeric::F64, Engine::Interp) => "",
    }
}

/// The WAV outputs and the trace's columns (with `extra` ones) of `req`, checked before the
/// simulation, so that a misspelt output or plotted column fails at once.
fn check_outputs(
    program: &Program,
    req: &SimRequest,
    extra: &[(String, String)],
) -> Result<(Option<Vec<String>>, Trace), String> {
    let wav_outputs = req
        .wav
        .map(|chosen| wav_outputs(program, chosen))
        .transpose()?;
    let mut columns = tactus_compiler::sim::trace_columns(program);
    for (name, unit) in extra {
        columns.add_column(name.clone(), unit.clone(), ColumnKind::Output);
    }
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
    Ok((wav_outputs, columns))
}

/// Runs `run` on an engine of `program` for `numeric` and `engine`: the f64 or fixed-point
/// interpreter, or its JIT (the same bits). Returns what `run` returns and, in fixed point,
/// the plan's warnings.
///
/// Errors: a JIT that does not compile.
pub fn with_engine<R>(
    program: &Program,
    numeric: Numeric,
    engine: Engine,
    run: &mut dyn FnMut(&mut dyn tactus_compiler::sim::Engine) -> R,
) -> Result<(R, Vec<Diagnostic>), String> {
    Ok(match (numeric, engine) {
        (Numeric::F64, Engine::Interp) => (
            run(&mut tactus_compiler::interp::Instance::new(program)),
            Vec::new(),
        ),
        (Numeric::F64, Engine::Jit) => {
            let jit = tactus_jit::JitProgram::compile(program).map_err(|e| format!("JIT: {e}"))?;
            let mut engine = JitEngine(tactus_jit::JitInstance::new(&jit));
            (run(&mut engine), Vec::new())
        }
        (Numeric::Fixed, engine) => {
            let fp = tactus_compiler::fixed::FixedProgram::new(program);
            let r = if engine == Engine::Jit {
                let jit = tactus_jit::fixed::FixedJitProgram::compile(&fp)
                    .map_err(|e| format!("JIT: {e}"))?;
                let mut engine =
                    FixedJitEngine(tactus_jit::fixed::FixedJitInstance::new(&jit), &fp);
                run(&mut engine)
            } else {
                run(&mut tactus_compiler::fixed::interp::FixedInstance::new(&fp))
            };
            (r, fp.warnings.clone())
        }
    })
}

/// The key travel a touch needs of `program`: its first sensor, from 0 at rest to the key
/// bed (a length of at most 100 mm), on a keyboard instrument; the bed (its upper bound).
///
/// Errors: a pen instrument, or a first sensor that is not such a key.
pub fn key_dip(program: &Program, what: &str) -> Result<f64, String> {
    if program.is_pen() {
        return Err(format!(
            "instrument `{}` is a pen instrument (a vector force): {what} needs a key",
            program.name
        ));
    }
    let Some(sensor) = program.sensors.first() else {
        return Err(format!(
            "instrument `{}` has no sensor: {what} needs a key",
            program.name
        ));
    };
    let (lo, dip) = sensor.range;
    let length = sensor.dim == tactus_compiler::units::Dim::LENGTH;
    if lo != 0.0 || !(dip > 0.0 && dip <= 0.1) || !length {
        return Err(format!(
            "instrument `{}`: {what} reads the first sensor `{}` as the key travel, a length from 0 at rest to the key bed (at most 100 mm); its range is [{lo}, {dip}] {}",
            program.name, sensor.name, sensor.dim.unit_string()
        ));
    }
    Ok(dip)
}

/// The finger's columns a touch run adds to the trace: the pulp's force on the key and the
/// finger's speed.
fn touch_columns() -> Vec<(String, String)> {
    vec![
        ("finger".to_string(), "N".to_string()),
        ("finger.speed".to_string(), "m/s".to_string()),
    ]
}

/// `req` with a touch: the key moved by a finger ([`TouchPlay`], [`Fingertip::default`])
/// for [`TOUCH_RUN_S`], the finger meeting it at [`TOUCH_START_S`].
fn simulate_touch(program: &Program, req: &SimRequest, touch: Touch) -> Result<SimRun, String> {
    let g = &req.gesture;
    if [g.depth_m, g.speed_m_per_s, g.stroke_m, g.across_m]
        .iter()
        .any(Option::is_some)
    {
        return Err(
            "--depth, --speed, --stroke and --across apply to the pen gestures, not to a --touch"
                .to_string(),
        );
    }
    if req.dip_m.is_some() {
        return Err(
            "--dip applies to the built-in key stimuli; a --touch moves the key to its sensor's bed"
                .to_string(),
        );
    }
    let dip = key_dip(program, "a --touch")?;
    let extra = touch_columns();
    let (wav_outputs, _) = check_outputs(program, req, &extra)?;
    let fs = program.sample_rate_hz;
    let samples = (TOUCH_RUN_S * fs) as usize;
    let ((trace, summary), fixed_warnings) =
        with_engine(program, req.numeric, req.engine, &mut |engine| {
            let mut play = TouchPlay::new(
                touch,
                dip,
                Fingertip::default(),
                fs,
                TOUCH_START_S,
                TOUCH_HOLD_N,
                TOUCH_LIFT_S,
            );
            let (trace, summary, _) = tactus_compiler::sim::simulate_driven(
                program,
                engine,
                samples,
                &extra,
                &mut |n, previous| {
                    if n > 0 {
                        play.step(previous.map_or(0.0, |o| o.total));
                    }
                    let p = play.player();
                    (
                        vec![play.key_m()],
                        vec![
                            p.contact_n().unwrap_or(0.0),
                            p.finger_speed_mps().unwrap_or(0.0),
                        ],
                    )
                },
            );
            (trace, summary)
        })?;
    let name = touch.label().replace(':', "-").replace("m/s", "mps");
    Ok(SimRun {
        title: format!("{} — {} touch", program.name, touch.label()),
        stem: format!("{}-{name}{}", program.name, suffix(req)),
        stimulus: touch.label(),
        samples,
        duration_s: samples as f64 / fs,
        notes: Vec::new(),
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
    crate::play::output::write_mono_wav(path, &mix, fs).map_err(|e| format!("--wav: {e}"))
}

/// Writes a run's files into `out` (created if missing): `STEM.csv` (the trace),
/// `STEM-forces.svg`, the WAV at `wav` when the run has WAV outputs, `STEM-outputs.svg`
/// when the program has outputs, and `STEM-plot.svg` of `plots` when some are asked for.
/// Returns the paths written, in that order.
///
/// Errors, as messages naming the file: one that cannot be written or plotted; and a
/// non-finite value in the trace (a division by zero, an overflow or an unstable scheme in
/// an f64 engine; the fixed engines saturate): then only the CSV is written, to look at.
pub fn write_files(
    program: &Program,
    run: &SimRun,
    plots: &[String],
    out: &Path,
    wav: Option<&Path>,
) -> Result<Vec<PathBuf>, String> {
    let (trace, stem, title) = (&run.trace, &run.stem, &run.title);
    std::fs::create_dir_all(out).map_err(|e| format!("cannot create `{}`: {e}", out.display()))?;
    let csv = out.join(format!("{stem}.csv"));
    trace.write_csv_file(&csv).map_err(|e| e.to_string())?;
    if let Some((column, n, v)) = tactus_compiler::sim::first_non_finite(trace) {
        return Err(format!(
            "{title}: `{column}` is {v} at sample {n} (t = {:.6} s): the simulation computed a non-finite value (a division by zero, an overflow or an unstable scheme); the trace up to there is in {}",
            n as f64 / program.sample_rate_hz,
            csv.display(),
        ));
    }
    let forces_svg = out.join(format!("{stem}-forces.svg"));
    plot::plot_forces(trace, title, &forces_svg).map_err(|e| e.to_string())?;
    let mut written = vec![csv, forces_svg];
    if let (Some(wav), Some(names)) = (wav, &run.wav_outputs) {
        write_wav(trace, names, program.sample_rate_hz, wav)?;
        written.push(wav.to_path_buf());
    }
    if !program.outputs.is_empty() {
        let names: Vec<&str> = program.outputs.iter().map(|o| o.name.as_str()).collect();
        let svg = out.join(format!("{stem}-outputs.svg"));
        plot::plot_columns(trace, &names, title, &svg).map_err(|e| e.to_string())?;
        written.push(svg);
    }
    if !plots.is_empty() {
        let svg = out.join(format!("{stem}-plot.svg"));
        plot::plot_named(trace, plots, title, &svg)?;
        written.push(svg);
    }
    Ok(written)
}

/// What a run says: the lines to print (the title with the samples, duration and the total
/// force's range — per axis for a pen —, then each event with its arguments) and the
/// warnings (each state saturated to its range, with how often).
pub fn report(program: &Program, run: &SimRun) -> (Vec<String>, Vec<String>) {
    let fs = program.sample_rate_hz;
    let totals: Vec<String> = force_ranges(program, &run.trace)
        .into_iter()
        .map(|(name, lo, hi)| {
            let what = if name == "total" { "total force" } else { name };
            format!("{what} {lo:.3} N … {hi:.3} N")
        })
        .collect();
    let mut lines = vec![format!(
        "{}: {} samples ({:.3} s at {} Hz), {}",
        run.title,
        run.samples,
        run.duration_s,
        fs,
        totals.join(", ")
    )];
    for (n, name, a) in &run.summary.events {
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
        lines.push(format!(
            "  event {name} at {:.2} ms: {}",
            *n as f64 / fs * 1e3,
            args_text.join(", ")
        ));
    }
    let warnings = program
        .states
        .iter()
        .zip(&run.summary.saturations)
        .filter(|(_, &count)| count > 0)
        .map(|(s, count)| {
            format!(
                "state `{}` was saturated to its range [{}, {}] {} {count} times; widen the range if this is not intended",
                s.name, s.range.0, s.range.1, s.dim.unit_string()
            )
        })
        .collect();
    (lines, warnings)
}

/// The stimuli `tactus sim` takes, for its `--help`: the built-in key stimuli and pen
/// gestures with their descriptions, the CSV formats, the files written, examples.
pub fn stimulus_help() -> String {
    let mut s = String::from(
        "Built-in key stimuli (key travel at the front, position-driven, first sensor only;\n\
         the other sensors read their lower bound):\n",
    );
    for (n, d) in tactus_runtime::stimulus::builtin_names() {
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
    s.push_str(&format!(
        "\nA pianist's touch (--touch, instead of --stimulus): a finger of {finger:.0} g on a key of\n\
         {key:.0} g at the key front, joined by the fingertip's pulp, moves the key against the\n\
         instrument's force (one sample of delay, as on the board). `pressed:FORCE` lays the\n\
         finger on the key and pushes (e.g. pressed:8N); `struck:SPEED` hits the key at that\n\
         speed, then pushes (e.g. struck:2.5m/s); a level (pressed:pp … struck:fff) takes its\n\
         row below. The push rises over {rise:.0} ms and lasts until {after:.0} ms after the key\n\
         reaches its bed; {hold} N then hold the key down until the finger lifts at {lift} s.\n\
         The finger meets the key at {start:.0} ms. Extra trace columns: `finger` (the pulp's force\n\
         on the key, N) and `finger.speed` (m/s).\n",
        finger = Fingertip::default().finger_kg * 1e3,
        key = Fingertip::default().key_kg * 1e3,
        rise = tactus_runtime::player::PUSH_RISE_S * 1e3,
        after = tactus_runtime::player::PUSH_AFTER_BOTTOM_S * 1e3,
        hold = TOUCH_HOLD_N,
        lift = TOUCH_LIFT_S,
        start = TOUCH_START_S * 1e3,
    ));
    s.push_str("  level   pressed push   struck speed\n");
    for level in tactus_runtime::player::Dynamic::ALL {
        let (p, st) = (
            Touch::at(tactus_runtime::player::TouchKind::Pressed, level),
            Touch::at(tactus_runtime::player::TouchKind::Struck, level),
        );
        s.push_str(&format!(
            "  {:<6} {:>8} N     {:>6} m/s\n",
            level.name(),
            p.push_n,
            st.contact_mps
        ));
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
         \x20         tactus sim grand_piano --touch struck:2.5m/s --plot finger\n\
         \x20         tactus sim rubbed_bank --stimulus press-rub --depth 5 --speed 0.1 --plot force.x",
    );
    s
}
