//! Host simulation: a program driven by a stimulus on any engine, recorded as a [`Trace`].
//!
//! The stimulus of every sensor is [`SensorStimulus`] (a key stimulus, a
//! multi-sensor CSV, or a pen gesture of [`gesture`]); [`resolve`] picks one from a
//! command-line word, as `tactus sim --stimulus` does. Every engine ([`Engine`]: the f64
//! interpreter or the fixed interpreter) clamps a reading to its sensor's declared range (a
//! missing reading is the lower bound); the trace records the clamped values.
//!
//! # The trace
//!
//! One row per sample: time, sensors, every force term, the total, states, modes, outputs
//! and one column per event argument (`strike.velocity`, NaN where the event did not fire).
//! The total is the column `total` for a keyboard instrument; a pen instrument (one with a
//! vector force) has the three columns `force.x`, `force.y`, `force.z` there instead (its
//! per-axis totals, newtons; `force.z` is the total force word), and its compiler-generated
//! outputs `force.x`, `force.y` are not repeated among the outputs.

mod gesture;
mod sensor_stimulus;

pub use gesture::{gesture, gesture_names, is_gesture, pen_sensors, GestureConfig};
pub use sensor_stimulus::{sensor_csv, SensorStimulus, SensorStimulusError, MAX_CSV_BYTES};

use crate::fixed::interp::FixedInstance;
use crate::interp::{Instance, SampleOut};
use crate::ir::{AxisTotal, Program};
use std::path::Path;
use tactus_runtime::stimulus::{self, Stimulus};
use tactus_runtime::trace::{ColumnKind, Trace};

/// The pen gestures as (name, one-line description), for `--help` and for the error that
/// lists every stimulus ([`SensorStimulusError::Unknown`]). Keep in step with [`gesture`].
const GESTURES: &[(&str, &str)] = &[
    (
        "press-rub",
        "press to DEPTH, rub 2 cycles back and forth over STROKE (20 mm) around the middle of the stroke axis (x) at SPEED (0.1 m/s), release",
    ),
    (
        "bow-stroke",
        "press to DEPTH, one stroke over STROKE (60 % of the stroke axis' range, centred) at SPEED (0.1 m/s), release",
    ),
    (
        "pluck",
        "press to DEPTH, cross the middle of the stroke axis (x, the plucking point) over STROKE (20 mm) at SPEED (0.2 m/s), release",
    ),
];

/// What a simulation produced besides the trace.
#[derive(Clone, Debug, PartialEq)]
pub struct SimSummary {
    /// Number of times each state's write was saturated to its declared range (program order).
    pub saturations: Vec<u64>,
    /// Every emitted event: (sample index, event name, argument values in SI).
    pub events: Vec<(usize, String, Vec<f64>)>,
}

/// An engine that runs one key sample by sample, seen in SI units.
pub trait Engine {
    /// Runs one sample on SI sensor readings.
    fn step_si(&mut self, sensors: &[f64]) -> SampleOut;
    /// Current states, SI, in program order.
    fn states_si(&self) -> Vec<f64>;
    /// Current mode variant indices.
    fn modes_now(&self) -> Vec<u32>;
    /// Saturations of state writes so far, per state.
    fn state_saturations(&self) -> Vec<u64>;
}

impl Engine for Instance<'_> {
    fn step_si(&mut self, sensors: &[f64]) -> SampleOut {
        self.step(sensors).clone()
    }
    fn states_si(&self) -> Vec<f64> {
        self.states().to_vec()
    }
    fn modes_now(&self) -> Vec<u32> {
        self.modes().to_vec()
    }
    fn state_saturations(&self) -> Vec<u64> {
        self.saturations().to_vec()
    }
}

impl Engine for FixedInstance<'_> {
    fn step_si(&mut self, sensors: &[f64]) -> SampleOut {
        let fp = self.program();
        self.step(sensors).to_si(fp)
    }
    fn states_si(&self) -> Vec<f64> {
        self.program().states_si(self.states())
    }
    fn modes_now(&self) -> Vec<u32> {
        self.modes().to_vec()
    }
    fn state_saturations(&self) -> Vec<u64> {
        self.program().declared_saturations(self.saturations())
    }
}

/// The stimulus a command-line word names, for `program` at `sample_rate_hz`: an existing
/// file is read with [`sensor_csv`]; a gesture name is made by [`gesture`] with `config`;
/// otherwise a built-in key stimulus (`tactus_runtime::stimulus::builtin`) of dip `dip_m`
/// (default: the first sensor's upper bound) drives the first sensor.
///
/// # Errors
///
/// As [`sensor_csv`] and [`gesture`]; [`SensorStimulusError::Unknown`] (listing the key
/// stimuli and the gestures) for any other name; [`SensorStimulusError::NotAPen`] when the
/// program has no sensor.
pub fn resolve(
    program: &Program,
    word: &str,
    dip_m: Option<f64>,
    config: &GestureConfig,
    sample_rate_hz: f64,
) -> Result<SensorStimulus, SensorStimulusError> {
    let path = Path::new(word);
    if path.is_file() {
        return sensor_csv(program, path, sample_rate_hz);
    }
    if is_gesture(word) {
        return gesture(program, word, config, sample_rate_hz);
    }
    if !stimulus::builtin_names().iter().any(|(n, _)| *n == word) {
        return Err(SensorStimulusError::Unknown {
            name: word.to_string(),
        });
    }
    let Some(key) = program.sensors.first() else {
        return Err(SensorStimulusError::NotAPen {
            gesture: word.to_string(),
            instrument: program.name.clone(),
            reason: "has no sensor".to_string(),
        });
    };
    let key = stimulus::builtin(word, dip_m.unwrap_or(key.range.1), sample_rate_hz)?;
    Ok(SensorStimulus::from_key(program, &key))
}

/// The most values (samples × columns of [`trace_columns`]) a simulation's trace may hold:
/// 2²⁷ f64, 1 GiB. The caller checks [`trace_values`] against it before simulating, so a
/// long stimulus on a wide instrument is an error, not an out-of-memory abort.
pub const MAX_TRACE_VALUES: usize = 1 << 27;

/// How many values the trace of `program` over `samples` samples holds (saturating).
pub fn trace_values(program: &Program, samples: usize) -> usize {
    trace_columns(program).columns.len().saturating_mul(samples)
}

/// The first value of `trace` that is NaN or ±∞ outside the event columns (where NaN means
/// "did not fire"): (column name, sample index, value). An f64 engine that computes one has
/// lost the meaning of the program (a division by zero, an overflow, an unstable scheme).
pub fn first_non_finite(trace: &Trace) -> Option<(String, usize, f64)> {
    trace
        .columns
        .iter()
        .filter(|c| c.kind != ColumnKind::Event)
        .filter_map(|c| {
            c.values
                .iter()
                .position(|v| !v.is_finite())
                .map(|n| (c.name.clone(), n, c.values[n]))
        })
        .min_by_key(|(_, n, _)| *n)
}

/// Which outputs of `program` are a pen instrument's axis totals (`force.x`, `force.y`),
/// one flag per output: the trace shows them with the total, not among the outputs.
fn axis_outputs(program: &Program) -> Vec<bool> {
    let mut mask = vec![false; program.outputs.len()];
    for (_, t) in &program.force_axes {
        if let AxisTotal::Output(o) = t {
            mask[o.index()] = true;
        }
    }
    mask
}

/// An empty trace with the columns a simulation of `program` records, in order: time,
/// sensors, forces, total (`total`; for a pen instrument `force.x`, `force.y`, `force.z`),
/// states, modes, outputs, event arguments (`event.arg`).
pub fn trace_columns(program: &Program) -> Trace {
    let mut trace = Trace::new(program.sample_rate_hz);
    trace.add_column("time", "s", ColumnKind::Time);
    for s in &program.sensors {
        trace.add_column(s.name.clone(), s.dim.unit_string(), ColumnKind::Sensor);
    }
    for f in &program.forces {
        trace.add_column(f.name.clone(), "N", ColumnKind::Force);
    }
    if program.is_pen() {
        // The z total is the force word, the one the force plot shows as the total.
        for (axis, t) in &program.force_axes {
            let kind = match t {
                AxisTotal::Total => ColumnKind::TotalForce,
                AxisTotal::Output(_) => ColumnKind::Output,
            };
            trace.add_column(format!("force.{axis}"), "N", kind);
        }
    } else {
        trace.add_column("total", "N", ColumnKind::TotalForce);
    }
    for s in &program.states {
        trace.add_column(s.name.clone(), s.dim.unit_string(), ColumnKind::State);
    }
    for m in &program.modes {
        trace.add_column(m.name.clone(), "", ColumnKind::Mode);
    }
    let hidden = axis_outputs(program);
    for (o, _) in program.outputs.iter().zip(&hidden).filter(|(_, &h)| !h) {
        let unit = match o.ty {
            crate::ir::Ty::Real(d) => d.unit_string(),
            _ => String::new(),
        };
        trace.add_column(o.name.clone(), unit, ColumnKind::Output);
    }
    for e in &program.events {
        for (a, d) in &e.args {
            trace.add_column(
                format!("{}.{a}", e.name),
                d.unit_string(),
                ColumnKind::Event,
            );
        }
    }
    trace
}

/// Runs `program` over a key stimulus with the f64 reference interpreter: the key drives
/// the first sensor, the others read their lower bound ([`SensorStimulus::from_key`]).
///
/// The stimulus's sample rate should equal the program's (the dynamics were discretised for
/// it); the caller checks this, the trace records the program's.
pub fn simulate(program: &Program, stimulus: &Stimulus) -> (Trace, SimSummary) {
    simulate_with(program, &mut Instance::new(program), stimulus)
}

/// Runs `program` over a key stimulus with any engine built from it (see [`simulate`]).
pub fn simulate_with(
    program: &Program,
    engine: &mut dyn Engine,
    stimulus: &Stimulus,
) -> (Trace, SimSummary) {
    simulate_sensors_with(
        program,
        engine,
        &SensorStimulus::from_key(program, stimulus),
    )
}

/// Runs `program` over a stimulus of every sensor with the f64 reference interpreter.
pub fn simulate_sensors(program: &Program, stimulus: &SensorStimulus) -> (Trace, SimSummary) {
    simulate_sensors_with(program, &mut Instance::new(program), stimulus)
}

/// Runs `program` over a stimulus of every sensor with any engine built from it. Readings
/// are matched to sensors by position (a stimulus made for `program` has them in its
/// order); a missing reading is the sensor's lower bound. The trace records each reading
/// clamped into its range, as the engines read it.
pub fn simulate_sensors_with(
    program: &Program,
    engine: &mut dyn Engine,
    stimulus: &SensorStimulus,
) -> (Trace, SimSummary) {
    let mut trace = trace_columns(program);
    let mut event_col = Vec::new();
    let mut first =
        trace.columns.len() - program.events.iter().map(|e| e.args.len()).sum::<usize>();
    for e in &program.events {
        event_col.push(first);
        first += e.args.len();
    }
    let mut row = vec![0.0; trace.columns.len()];
    let hidden = axis_outputs(program);
    let mut events = Vec::new();
    for n in 0..stimulus.len() {
        let sensors = stimulus.row(n);
        let out = engine.step_si(sensors);
        let mut c = 0;
        row[c] = n as f64 / program.sample_rate_hz;
        c += 1;
        for (i, s) in program.sensors.iter().enumerate() {
            let x = sensors.get(i).copied().unwrap_or(s.range.0);
            row[c] = if x.is_nan() {
                s.range.0
            } else {
                x.clamp(s.range.0, s.range.1)
            };
            c += 1;
        }
        for f in &out.forces {
            row[c] = *f;
            c += 1;
        }
        if program.is_pen() {
            for (_, t) in &program.force_axes {
                row[c] = match t {
                    AxisTotal::Total => out.total,
                    AxisTotal::Output(o) => out.outputs[o.index()],
                };
                c += 1;
            }
        } else {
            row[c] = out.total;
            c += 1;
        }
        for s in engine.states_si() {
            row[c] = s;
            c += 1;
        }
        for m in engine.modes_now() {
            row[c] = m as f64;
            c += 1;
        }
        for (o, _) in out.outputs.iter().zip(&hidden).filter(|(_, &h)| !h) {
            row[c] = *o;
            c += 1;
        }
        for x in &mut row[c..] {
            *x = f64::NAN;
        }
        for (e, args) in &out.events {
            let start = event_col[e.index()];
            row[start..start + args.len()].copy_from_slice(args);
            events.push((n, program.events[e.index()].name.clone(), args.clone()));
        }
        // Rows always match the column count built above.
        let _ = trace.push_row(&row);
    }
    (
        trace,
        SimSummary {
            saturations: engine.state_saturations(),
            events,
        },
    )
}
