//! Host simulation with the reference interpreter: a program driven by a key stimulus,
//! recorded as a [`Trace`].
//!
//! The stimulus feeds the program's first sensor; further sensors read their lower bound.
//! One row per sample: time, sensors, every force term, the total, states, modes, outputs
//! and one column per event argument (`strike.velocity`, NaN where the event did not fire).

use crate::fixed::interp::FixedInstance;
use crate::interp::{Instance, SampleOut};
use crate::ir::Program;
use tactus_runtime::stimulus::Stimulus;
use tactus_runtime::trace::{ColumnKind, Trace};

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
        let fp = self.program();
        self.states()
            .iter()
            .zip(&fp.state_frac)
            .map(|(&x, &f)| tactus_runtime::fixed::to_f64(x, f))
            .collect()
    }
    fn modes_now(&self) -> Vec<u32> {
        self.modes().to_vec()
    }
    fn state_saturations(&self) -> Vec<u64> {
        self.saturations().to_vec()
    }
}

/// Runs `program` over `stimulus` with the f64 reference interpreter.
///
/// The stimulus's sample rate should equal the program's (the dynamics were discretised for
/// it); the caller checks this, the trace records the program's.
pub fn simulate(program: &Program, stimulus: &Stimulus) -> (Trace, SimSummary) {
    simulate_with(program, &mut Instance::new(program), stimulus)
}

/// Runs `program` over `stimulus` with any engine built from it.
pub fn simulate_with(
    program: &Program,
    engine: &mut dyn Engine,
    stimulus: &Stimulus,
) -> (Trace, SimSummary) {
    let mut trace = Trace::new(program.sample_rate_hz);
    trace.add_column("time", "s", ColumnKind::Time);
    for s in &program.sensors {
        trace.add_column(s.name.clone(), s.dim.unit_string(), ColumnKind::Sensor);
    }
    for f in &program.forces {
        trace.add_column(f.name.clone(), "N", ColumnKind::Force);
    }
    trace.add_column("total", "N", ColumnKind::TotalForce);
    for s in &program.states {
        trace.add_column(s.name.clone(), s.dim.unit_string(), ColumnKind::State);
    }
    for m in &program.modes {
        trace.add_column(m.name.clone(), "", ColumnKind::Mode);
    }
    for o in &program.outputs {
        let unit = match o.ty {
            crate::ir::Ty::Real(d) => d.unit_string(),
            _ => String::new(),
        };
        trace.add_column(o.name.clone(), unit, ColumnKind::Output);
    }
    let mut event_col = Vec::new();
    for e in &program.events {
        event_col.push(trace.columns.len());
        for (a, d) in &e.args {
            trace.add_column(
                format!("{}.{a}", e.name),
                d.unit_string(),
                ColumnKind::Event,
            );
        }
    }
    let mut row = vec![0.0; trace.columns.len()];
    let mut events = Vec::new();
    for (n, &key) in stimulus.key.iter().enumerate() {
        let reading = [key];
        let sensors = &reading[..program.sensors.len().min(1)];
        let out = engine.step_si(sensors);
        let mut c = 0;
        row[c] = n as f64 / program.sample_rate_hz;
        c += 1;
        for (i, s) in program.sensors.iter().enumerate() {
            row[c] = sensors
                .get(i)
                .copied()
                .unwrap_or(s.range.0)
                .clamp(s.range.0, s.range.1);
            c += 1;
        }
        for f in &out.forces {
            row[c] = *f;
            c += 1;
        }
        row[c] = out.total;
        c += 1;
        for s in engine.states_si() {
            row[c] = s;
            c += 1;
        }
        for m in engine.modes_now() {
            row[c] = m as f64;
            c += 1;
        }
        for o in &out.outputs {
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
