//! Host simulation: a program driven by a stimulus on any engine, recorded as a [`Trace`].
//!
//! # Stimuli
//!
//! A [`SensorStimulus`] gives every sensor of a program a position per sample (SI). It is
//! made from
//!
//! * a **key stimulus** ([`tactus_runtime::stimulus::Stimulus`], built-in or the
//!   `key_mm`/`time_s,key_mm` CSV): the key travel drives the program's *first* sensor and
//!   every other sensor reads its lower bound ([`SensorStimulus::from_key`]);
//! * a **multi-sensor CSV** naming the sensors in its header ([`sensor_csv`]);
//! * a built-in **pen gesture** for contact-point instruments ([`gesture`], names in
//!   [`gesture_names`]): the pen's penetration into the surface or string, its position
//!   along the rubbing/bowing/plucking axis and, optionally, its position across (e.g. which
//!   string). An instrument with a vector sensor (`sensor pen: m in { z: …, x: …, y: … }`)
//!   gets them on its components `z`, `x` and `y` ([`pen_sensors`]); otherwise sensor 1 is
//!   the penetration, sensor 2 the stroke axis and sensor 3 across. The convention follows
//!   the 3-DoF pen of Onofrei, Fontana & Serafin 2023 (plucking, bowing and rubbing
//!   physically-based resonators).
//!
//! [`resolve`] picks one of them from a command-line word, as `tactus sim --stimulus` does.
//! Every engine clamps a reading to its sensor's declared range (a missing reading is the
//! lower bound); the trace records the clamped values.
//!
//! # Multi-sensor CSV format
//!
//! UTF-8, comma-separated, cells trimmed, lines starting with `#` and blank lines ignored,
//! no quoted commas. The header row names the columns:
//!
//! * an optional first column `time [s]` (or `time`, or `time_s`): sample times in seconds,
//!   strictly increasing, any spacing; the rows are linearly interpolated onto
//!   `t₀ + i/f_s` up to the last time. Without it, one row per sample at the program's rate;
//! * then one column per driven sensor, named as the sensor (`press`), optionally with its
//!   unit in brackets as in the trace CSV (`press [m]`). Values are in the sensor's **SI
//!   unit** (metres for a position: `0.005` is 5 mm); a bracketed unit other than the SI one
//!   is an error, so a file in millimetres cannot be read as metres by mistake.
//!
//! Sensors without a column read their lower bound. Values outside a sensor's range are
//! clamped into it and the clamp is reported in [`SensorStimulus::notes`]. A column that
//! names no sensor is an error naming the file, the column and the instrument's sensors; a
//! cell that is not a finite number names the line and the column. The header `key_mm` or
//! `time_s,key_mm` still selects the single-column key format (millimetres!).
//!
//! ```text
//! # rub at 0.1 m/s while pressed 5 mm
//! time [s],press [m],rub [m]
//! 0.00,0,0.040
//! 0.05,0.005,0.040
//! 0.25,0.005,0.060
//! 0.30,0,0.060
//! ```
//!
//! # The trace
//!
//! One row per sample: time, sensors, every force term, the total, states, modes, outputs
//! and one column per event argument (`strike.velocity`, NaN where the event did not fire).
//! The total is the column `total` for a keyboard instrument; a pen instrument (one with a
//! vector force) has the three columns `force.x`, `force.y`, `force.z` there instead (its
//! per-axis totals, newtons; `force.z` is the total force word), and its compiler-generated
//! outputs `force.x`, `force.y` are not repeated among the outputs.

use crate::fixed::interp::FixedInstance;
use crate::interp::{Instance, SampleOut};
use crate::ir::{AxisTotal, Program};
use std::fmt;
use std::path::{Path, PathBuf};
use tactus_runtime::stimulus::{self, Stimulus, StimulusError, MAX_SAMPLES};
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
        self.program().states_si(self.states())
    }
    fn modes_now(&self) -> Vec<u32> {
        self.modes().to_vec()
    }
    fn state_saturations(&self) -> Vec<u64> {
        self.program().declared_saturations(self.saturations())
    }
}

/// A stimulus for every sensor of one program: per sample, one SI reading per sensor in the
/// program's declaration order (row-major in [`SensorStimulus::values`]).
#[derive(Clone, Debug, PartialEq)]
pub struct SensorStimulus {
    /// Short name (built-in or gesture name, or the file's stem).
    pub name: String,
    /// One line saying what the stimulus does, with its actual numbers.
    pub description: String,
    /// Sample rate in hertz; sample `i` is at `i / sample_rate_hz` seconds.
    pub sample_rate_hz: f64,
    /// Sensor names, in program order (the width of a row).
    pub sensors: Vec<String>,
    /// Number of samples.
    pub samples: usize,
    /// Readings, SI, row-major: sample `n`, sensor `i` at `n * sensors.len() + i`
    /// (`samples * sensors.len()` values).
    pub values: Vec<f64>,
    /// What was adjusted to fit the program (values clamped into a sensor's range, options
    /// that do not apply), one sentence each, for the caller to show as warnings.
    pub notes: Vec<String>,
}

impl SensorStimulus {
    /// Number of samples.
    pub fn len(&self) -> usize {
        self.samples
    }

    /// True when the stimulus has no samples.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// Duration in seconds: number of samples divided by the sample rate.
    pub fn duration_s(&self) -> f64 {
        self.len() as f64 / self.sample_rate_hz
    }

    /// The readings of sample `n` (one per sensor, SI). Panics when `n >= self.len()`.
    pub fn row(&self, n: usize) -> &[f64] {
        let w = self.sensors.len();
        &self.values[n * w..(n + 1) * w]
    }

    /// Every reading of sensor `i` (SI), one per sample.
    pub fn channel(&self, i: usize) -> Vec<f64> {
        let w = self.sensors.len();
        (0..self.len()).map(|n| self.values[n * w + i]).collect()
    }

    /// A key stimulus on `program`: the key travel drives the first sensor, every other
    /// sensor reads its lower bound. The key travel is not clamped here (the engines clamp
    /// it), so [`simulate_sensors`] on the result is exactly [`simulate`] on `key`.
    pub fn from_key(program: &Program, key: &Stimulus) -> SensorStimulus {
        let w = program.sensors.len();
        let mut values = Vec::with_capacity(w * key.len());
        for &k in &key.key {
            for (i, s) in program.sensors.iter().enumerate() {
                values.push(if i == 0 { k } else { s.range.0 });
            }
        }
        // The engines clamp the key into the first sensor's range; say so when they will.
        let mut notes = Vec::new();
        if let Some(s) = program.sensors.first() {
            let (lo, hi) = s.range;
            let outside: Vec<f64> = key
                .key
                .iter()
                .copied()
                .filter(|k| !(lo..=hi).contains(k))
                .collect();
            if let Some(worst) = outside.iter().copied().max_by(|a, b| {
                (a - a.clamp(lo, hi))
                    .abs()
                    .total_cmp(&(b - b.clamp(lo, hi)).abs())
            }) {
                notes.push(format!(
                    "{}: {} of {} key positions are outside sensor `{}`'s range [{lo}, {hi}] {} (the farthest: {worst:e}) and are clamped into it",
                    key.name,
                    outside.len(),
                    key.len(),
                    s.name,
                    s.dim.unit_string()
                ));
            }
        }
        SensorStimulus {
            name: key.name.clone(),
            description: key.description.clone(),
            sample_rate_hz: key.sample_rate_hz,
            sensors: program.sensors.iter().map(|s| s.name.clone()).collect(),
            samples: key.len(),
            values,
            notes,
        }
    }

    /// Clamps every reading into its sensor's declared range and adds a note per sensor that
    /// needed it (how many samples, the range).
    fn clamp_to(&mut self, program: &Program, what: &str) {
        let w = self.sensors.len();
        for (i, s) in program.sensors.iter().enumerate() {
            let (lo, hi) = s.range;
            let mut clamped = 0usize;
            let mut n = i;
            while n < self.values.len() {
                let x = self.values[n];
                let y = x.clamp(lo, hi);
                if y != x {
                    clamped += 1;
                    self.values[n] = y;
                }
                n += w;
            }
            if clamped > 0 {
                self.notes.push(format!(
                    "{what}: {clamped} readings of sensor `{}` were outside its range [{lo}, {hi}] {} and were clamped into it",
                    s.name,
                    s.dim.unit_string()
                ));
            }
        }
    }
}

/// Why a [`SensorStimulus`] could not be made or read.
#[derive(Debug)]
pub enum SensorStimulusError {
    /// A key stimulus (built-in or key CSV) failed.
    Key(StimulusError),
    /// The name is neither a file, a key stimulus nor a gesture.
    Unknown {
        /// The name asked for.
        name: String,
    },
    /// A gesture was asked of an instrument that is not a contact-point instrument.
    NotAPen {
        /// The gesture.
        gesture: String,
        /// The instrument.
        instrument: String,
        /// Why (fewer than two sensors, or a sensor that is not a length).
        reason: String,
    },
    /// A gesture parameter is not finite and positive (or not finite).
    InvalidParameter {
        /// The parameter (`"speed"`, `"depth"`, …).
        name: &'static str,
        /// The value given, SI.
        value: f64,
        /// What it must be.
        expected: &'static str,
    },
    /// The file could not be read.
    Io {
        /// The file.
        path: PathBuf,
        /// What the operating system said.
        source: std::io::Error,
    },
    /// A header column names no sensor of the instrument.
    UnknownColumn {
        /// The file.
        path: PathBuf,
        /// The header cell as written.
        column: String,
        /// The instrument.
        instrument: String,
        /// Its sensors, `name [unit]`.
        sensors: Vec<String>,
    },
    /// A column's bracketed unit is not the sensor's SI unit.
    Unit {
        /// The file.
        path: PathBuf,
        /// The header cell as written.
        column: String,
        /// The unit found.
        unit: String,
        /// The sensor's SI unit.
        expected: String,
    },
    /// Two header cells name the same sensor (or the time twice).
    DuplicateColumn {
        /// The file.
        path: PathBuf,
        /// The header cell as written.
        column: String,
    },
    /// The time column is not the first.
    TimeNotFirst {
        /// The file.
        path: PathBuf,
    },
    /// A row has a different number of cells than the header.
    RowLength {
        /// The file.
        path: PathBuf,
        /// The line (1-based).
        line: usize,
        /// Cells in the row.
        cells: usize,
        /// Cells in the header.
        expected: usize,
    },
    /// A cell is not a finite number.
    Cell {
        /// The file.
        path: PathBuf,
        /// The line (1-based).
        line: usize,
        /// The column's header cell.
        column: String,
        /// The cell's text.
        text: String,
    },
    /// A time is not after the previous one.
    NotIncreasing {
        /// The file.
        path: PathBuf,
        /// The line (1-based).
        line: usize,
        /// The previous time, s.
        previous_s: f64,
        /// This line's time, s.
        time_s: f64,
    },
    /// No header, no sensor column, or no samples.
    Empty {
        /// The file.
        path: PathBuf,
        /// What is missing.
        missing: &'static str,
    },
    /// More than [`MAX_SAMPLES`] samples.
    TooLong {
        /// Where the stimulus came from.
        source: String,
        /// How many samples it would have.
        samples: f64,
    },
    /// A CSV file larger than [`MAX_CSV_BYTES`].
    TooLarge {
        /// The file.
        path: PathBuf,
        /// Its size.
        bytes: u64,
    },
}

impl fmt::Display for SensorStimulusError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        use SensorStimulusError as E;
        match self {
            E::Key(e) => e.fmt(f),
            E::Unknown { name } => {
                let keys: Vec<&str> = stimulus::builtin_names().iter().map(|p| p.0).collect();
                let pens: Vec<&str> = GESTURES.iter().map(|p| p.0).collect();
                write!(
                    f,
                    "unknown stimulus `{name}` (no such file either); the built-in key stimuli are: {}; the pen gestures are: {}",
                    keys.join(", "),
                    pens.join(", ")
                )
            }
            E::NotAPen {
                gesture,
                instrument,
                reason,
            } => write!(
                f,
                "gesture `{gesture}` needs a contact-point instrument (a vector sensor with z, the pen's penetration, and x, its position along the stroke, in m; or sensors 1 and 2 in that role); `{instrument}` {reason}"
            ),
            E::InvalidParameter {
                name,
                value,
                expected,
            } => write!(f, "gesture parameter `{name}` = {value}: must be {expected}"),
            E::Io { path, source } => {
                write!(f, "{}: cannot read stimulus: {source}", path.display())
            }
            E::UnknownColumn {
                path,
                column,
                instrument,
                sensors,
            } => write!(
                f,
                "{}:1: column `{column}` names no sensor of instrument `{instrument}` (its sensors: {}; an optional first column `time [s]`)",
                path.display(),
                sensors.join(", ")
            ),
            E::Unit {
                path,
                column,
                unit,
                expected,
            } => write!(
                f,
                "{}:1: column `{column}`: unit `{unit}`, but stimulus values are SI: write `[{expected}]` and the values in {expected}",
                path.display()
            ),
            E::DuplicateColumn { path, column } => write!(
                f,
                "{}:1: column `{column}` appears twice",
                path.display()
            ),
            E::TimeNotFirst { path } => write!(
                f,
                "{}:1: the time column must be the first column",
                path.display()
            ),
            E::RowLength {
                path,
                line,
                cells,
                expected,
            } => write!(
                f,
                "{}:{line}: {cells} cells, the header has {expected}",
                path.display()
            ),
            E::Cell {
                path,
                line,
                column,
                text,
            } => write!(
                f,
                "{}:{line}: column `{column}`: `{text}` is not a finite number",
                path.display()
            ),
            E::NotIncreasing {
                path,
                line,
                previous_s,
                time_s,
            } => write!(
                f,
                "{}:{line}: time {time_s} s is not after the previous time {previous_s} s (times must be strictly increasing)",
                path.display()
            ),
            E::Empty { path, missing } => {
                write!(f, "{}: empty stimulus file: no {missing}", path.display())
            }
            E::TooLong { source, samples } => write!(
                f,
                "stimulus `{source}` would have {} samples, more than the limit of {MAX_SAMPLES} (or more than {MAX_TRACE_VALUES} values over all its sensors)",
                if *samples < 1e15 { format!("{samples:.0}") } else { format!("{samples:.3e}") }
            ),
            E::TooLarge { path, bytes } => write!(
                f,
                "{}: {bytes} bytes, more than the {MAX_CSV_BYTES} a stimulus file may have",
                path.display()
            ),
        }
    }
}

impl std::error::Error for SensorStimulusError {
    fn source(&self) -> Option<&(dyn std::error::Error + 'static)> {
        match self {
            SensorStimulusError::Key(e) => Some(e),
            SensorStimulusError::Io { source, .. } => Some(source),
            _ => None,
        }
    }
}

impl From<StimulusError> for SensorStimulusError {
    fn from(e: StimulusError) -> Self {
        SensorStimulusError::Key(e)
    }
}

/// A header cell split into name and optional bracketed unit: `press [m]` → (`press`,
/// `Some("m")`).
fn split_header(cell: &str) -> (&str, Option<&str>) {
    let cell = cell.trim().trim_matches('"').trim();
    if let (Some(open), true) = (cell.rfind('['), cell.ends_with(']')) {
        (
            cell[..open].trim(),
            Some(cell[open + 1..cell.len() - 1].trim()),
        )
    } else {
        (cell, None)
    }
}

/// Reads a stimulus file for `program` at `sample_rate_hz`: the single-column key formats
/// (`key_mm`, `time_s,key_mm`; see [`tactus_runtime::stimulus`]) drive the first sensor, any
/// other header is the multi-sensor format of the module documentation.
///
/// # Errors
///
/// Every [`SensorStimulusError`] about files; each names the file, and the line and column
/// where there is one.
pub fn sensor_csv(
    program: &Program,
    path: &Path,
    sample_rate_hz: f64,
) -> Result<SensorStimulus, SensorStimulusError> {
    let io = |source| SensorStimulusError::Io {
        path: path.to_path_buf(),
        source,
    };
    // The whole file is read at once: bound it first (a row per sample at MAX_SAMPLES rows
    // of a few cells is far below this).
    let len = std::fs::metadata(path).map_err(io)?.len();
    if len > MAX_CSV_BYTES {
        return Err(SensorStimulusError::TooLarge {
            path: path.to_path_buf(),
            bytes: len,
        });
    }
    let text = std::fs::read_to_string(path).map_err(io)?;
    // A UTF-8 byte-order mark (as spreadsheet programs write) is not part of the header.
    let text = text.strip_prefix('\u{FEFF}').unwrap_or(&text);
    let mut lines = text
        .lines()
        .enumerate()
        .map(|(i, l)| (i + 1, l.trim()))
        .filter(|(_, l)| !l.is_empty() && !l.starts_with('#'));
    let err_path = || path.to_path_buf();
    let Some((_, header)) = lines.next() else {
        return Err(SensorStimulusError::Empty {
            path: err_path(),
            missing: "header row",
        });
    };
    let cells: Vec<&str> = header.split(',').map(str::trim).collect();
    let plain: Vec<&str> = cells.iter().map(|c| c.trim_matches('"')).collect();
    if plain == ["key_mm"] || plain == ["time_s", "key_mm"] {
        let key = stimulus::from_csv(path, sample_rate_hz)?;
        return Ok(SensorStimulus::from_key(program, &key));
    }
    // Column j of the file → Some(sensor index), or None for the time column.
    let mut targets: Vec<Option<usize>> = Vec::with_capacity(cells.len());
    for (j, cell) in cells.iter().enumerate() {
        let (name, unit) = split_header(cell);
        let is_time = (name == "time" && matches!(unit, None | Some("s")))
            || (name == "time_s" && unit.is_none());
        if is_time {
            if j != 0 {
                return Err(SensorStimulusError::TimeNotFirst { path: err_path() });
            }
            targets.push(None);
            continue;
        }
        let Some(i) = program.sensors.iter().position(|s| s.name == name) else {
            return Err(SensorStimulusError::UnknownColumn {
                path: err_path(),
                column: cell.to_string(),
                instrument: program.name.clone(),
                sensors: program
                    .sensors
                    .iter()
                    .map(|s| format!("{} [{}]", s.name, s.dim.unit_string()))
                    .collect(),
            });
        };
        let si = program.sensors[i].dim.unit_string();
        if let Some(u) = unit {
            if u != si {
                return Err(SensorStimulusError::Unit {
                    path: err_path(),
                    column: cell.to_string(),
                    unit: u.to_string(),
                    expected: si,
                });
            }
        }
        if targets.contains(&Some(i)) {
            return Err(SensorStimulusError::DuplicateColumn {
                path: err_path(),
                column: cell.to_string(),
            });
        }
        targets.push(Some(i));
    }
    let timed = targets.first() == Some(&None);
    if targets.iter().all(Option::is_none) {
        return Err(SensorStimulusError::Empty {
            path: err_path(),
            missing: "sensor column",
        });
    }
    let w = program.sensors.len();
    let lower: Vec<f64> = program.sensors.iter().map(|s| s.range.0).collect();
    let mut times = Vec::new();
    let mut rows: Vec<f64> = Vec::new();
    for (line, l) in lines {
        let row: Vec<&str> = l.split(',').map(|c| c.trim()).collect();
        if row.len() != cells.len() {
            return Err(SensorStimulusError::RowLength {
                path: err_path(),
                line,
                cells: row.len(),
                expected: cells.len(),
            });
        }
        rows.extend_from_slice(&lower);
        let base = rows.len() - w;
        for (j, text) in row.iter().enumerate() {
            let x = match text.parse::<f64>() {
                Ok(x) if x.is_finite() => x,
                _ => {
                    return Err(SensorStimulusError::Cell {
                        path: err_path(),
                        line,
                        column: cells[j].to_string(),
                        text: text.to_string(),
                    })
                }
            };
            match targets[j] {
                Some(i) => rows[base + i] = x,
                None => {
                    if let Some(&previous_s) = times.last() {
                        if x <= previous_s {
                            return Err(SensorStimulusError::NotIncreasing {
                                path: err_path(),
                                line,
                                previous_s,
                                time_s: x,
                            });
                        }
                    }
                    times.push(x);
                }
            }
        }
        if rows.len() / w.max(1) > MAX_SAMPLES {
            return Err(SensorStimulusError::TooLong {
                source: path.display().to_string(),
                samples: (rows.len() / w.max(1)) as f64,
            });
        }
    }
    if rows.is_empty() {
        return Err(SensorStimulusError::Empty {
            path: err_path(),
            missing: "samples",
        });
    }
    positive("sample_rate_hz", sample_rate_hz)?;
    let values = if timed {
        resample_rows(&times, &rows, w, sample_rate_hz, path)?
    } else {
        rows
    };
    let samples = values.len() / w;
    let name = path.file_stem().map_or_else(
        || path.display().to_string(),
        |s| s.to_string_lossy().into(),
    );
    let driven: Vec<&str> = targets
        .iter()
        .flatten()
        .map(|&i| program.sensors[i].name.as_str())
        .collect();
    let mut s = SensorStimulus {
        name,
        description: format!(
            "sensor positions ({}) from {}{}",
            driven.join(", "),
            path.display(),
            if timed {
                ", resampled"
            } else {
                ", one row per sample"
            }
        ),
        sample_rate_hz,
        sensors: program.sensors.iter().map(|s| s.name.clone()).collect(),
        samples,
        values,
        notes: Vec::new(),
    };
    s.clamp_to(program, &path.display().to_string());
    Ok(s)
}

/// Linear interpolation of rows (`w` values each, at strictly increasing `times`) onto
/// `times[0] + i / fs` up to the last time.
fn resample_rows(
    times: &[f64],
    rows: &[f64],
    w: usize,
    fs: f64,
    path: &Path,
) -> Result<Vec<f64>, SensorStimulusError> {
    let t0 = times[0];
    let samples = ((times[times.len() - 1] - t0) * fs).floor() + 1.0;
    if !samples.is_finite()
        || samples > MAX_SAMPLES as f64
        || samples * w as f64 > MAX_TRACE_VALUES as f64
    {
        return Err(SensorStimulusError::TooLong {
            source: path.display().to_string(),
            samples,
        });
    }
    let n = samples as usize;
    let mut out = Vec::with_capacity(n * w);
    let mut j = 0;
    for i in 0..n {
        let t = t0 + i as f64 / fs;
        while j + 2 < times.len() && times[j + 1] <= t {
            j += 1;
        }
        if j + 1 < times.len() {
            let u = ((t - times[j]) / (times[j + 1] - times[j])).clamp(0.0, 1.0);
            for k in 0..w {
                let (a, b) = (rows[j * w + k], rows[(j + 1) * w + k]);
                out.push(a + (b - a) * u);
            }
        } else {
            out.extend_from_slice(&rows[j * w..(j + 1) * w]);
        }
    }
    Ok(out)
}

fn positive(name: &'static str, value: f64) -> Result<(), SensorStimulusError> {
    if value.is_finite() && value > 0.0 {
        Ok(())
    } else {
        Err(SensorStimulusError::InvalidParameter {
            name,
            value,
            expected: "finite and > 0",
        })
    }
}

/// The pen gestures as (name, one-line description), for `--help`. Keep in step with
/// [`gesture`].
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

/// The built-in pen gestures as (name, one-line description), in a stable order.
pub fn gesture_names() -> &'static [(&'static str, &'static str)] {
    GESTURES
}

/// True when `name` is a built-in pen gesture.
pub fn is_gesture(name: &str) -> bool {
    GESTURES.iter().any(|(n, _)| *n == name)
}

/// Parameters of a pen gesture; `None` takes the gesture's default. SI units.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct GestureConfig {
    /// Penetration while pressed, m, as a reading of the depth sensor (a vector sensor's `z`,
    /// or sensor 1; see [`pen_sensors`]) (default: the middle of its
    /// range). Clamped into the range, with a note.
    pub depth_m: Option<f64>,
    /// Peak speed along the stroke axis (`x`, or sensor 2), m/s (defaults: 0.1 for `press-rub` and `bow-stroke`, inside
    /// the bow velocities |v_B| ≤ 0.4 m/s of Onofrei et al. 2023; 0.2 for `pluck`).
    pub speed_m_per_s: Option<f64>,
    /// Length of a stroke along the stroke axis, m (defaults: 20 mm for `press-rub` and
    /// `pluck`, 60 % of its range for `bow-stroke`). Clamped to its range, with a note.
    pub stroke_m: Option<f64>,
    /// Reading of the sensor across the stroke (`y`, or sensor 3; e.g. which string), m, held for the whole gesture
    /// (default: its lower bound). Clamped into the range, with a note.
    pub across_m: Option<f64>,
}

/// Rest before a gesture, s.
const REST_BEFORE_S: f64 = 0.020;
/// Press and release time, s (cycloidal).
const PRESS_S: f64 = 0.050;
/// Pause between the press and the stroke, and between the stroke and the release, s.
const SETTLE_S: f64 = 0.020;
/// Velocity blend at each end of a stroke, s.
const BLEND_S: f64 = 0.020;

/// One move of a [`Track`]: from `from` to `to` over `dur` seconds starting at `t0`, with
/// raised-cosine velocity blends of `blend` seconds at both ends (`blend <= dur / 2`; equal
/// to `dur / 2` it is the cycloidal law).
#[derive(Clone, Copy, Debug)]
struct Move {
    t0: f64,
    dur: f64,
    from: f64,
    to: f64,
    blend: f64,
}

impl Move {
    /// Position `tau` seconds into the move. The velocity is `v/2·(1 − cos(πτ/b))` over the
    /// blend-in, `v` in the middle, `v/2·(1 + cos(πs/b))` over the blend-out, with
    /// `v = D/(T − b)`: position C², the same law as the key stimuli
    /// (`tactus_runtime::stimulus`).
    fn at(&self, tau: f64) -> f64 {
        use std::f64::consts::PI;
        let (t, b) = (self.dur, self.blend);
        let v = (self.to - self.from) / (t - b);
        let tau = tau.clamp(0.0, t);
        let x = if tau <= b {
            v * (tau - b / PI * (PI * tau / b).sin()) / 2.0
        } else if tau <= t - b {
            v * b / 2.0 + v * (tau - b)
        } else {
            let s = tau - (t - b);
            v * b / 2.0 + v * (t - 2.0 * b) + v * (s + b / PI * (PI * s / b).sin()) / 2.0
        };
        // Never past either end, whatever the rounding.
        (self.from + x).clamp(self.from.min(self.to), self.from.max(self.to))
    }
}

/// One sensor's reading over time: a start and a sequence of moves.
#[derive(Clone, Debug)]
struct Track {
    start: f64,
    moves: Vec<Move>,
}

impl Track {
    fn new(start: f64) -> Self {
        Track {
            start,
            moves: Vec::new(),
        }
    }
    fn last(&self) -> f64 {
        self.moves.last().map_or(self.start, |m| m.to)
    }
    fn at(&self, t: f64) -> f64 {
        let mut x = self.start;
        for m in &self.moves {
            if t < m.t0 {
                break;
            }
            if t >= m.t0 + m.dur {
                x = m.to;
            } else {
                return m.at(t - m.t0);
            }
        }
        x
    }
}

/// The pen during a gesture: penetration and position tracks on one clock.
struct Pen {
    t: f64,
    press: Track,
    pos: Track,
}

impl Pen {
    fn wait(&mut self, s: f64) {
        self.t += s;
    }
    /// A cycloidal press (or release) to `x` over [`PRESS_S`].
    fn press_to(&mut self, x: f64) {
        let from = self.press.last();
        self.press.moves.push(Move {
            t0: self.t,
            dur: PRESS_S,
            from,
            to: x,
            blend: PRESS_S / 2.0,
        });
        self.t += PRESS_S;
    }
    /// A stroke to `x` at peak speed `v`: constant speed between [`BLEND_S`] blends, or a
    /// cycloid of peak speed `v` when the stroke is too short for both blends.
    fn stroke_to(&mut self, x: f64, v: f64) {
        let from = self.pos.last();
        let d = (x - from).abs();
        if d == 0.0 {
            return;
        }
        let (dur, blend) = if d / v >= BLEND_S {
            (d / v + BLEND_S, BLEND_S)
        } else {
            (2.0 * d / v, d / v)
        };
        self.pos.moves.push(Move {
            t0: self.t,
            dur,
            from,
            to: x,
            blend,
        });
        self.t += dur;
    }
}

/// The pen gesture `name` (see [`gesture_names`]) for `program`, sampled at
/// `sample_rate_hz`. The pen's penetration, its position along the stroke and (if there is
/// one) across drive the sensors [`pen_sensors`] picks (a vector sensor's `z`, `x`, `y`, or
/// sensors 1, 2, 3); every other sensor reads its lower bound.
/// Every move is C² (raised-cosine velocity blends, cycloidal presses), so the `d()`/`d2()`
/// differentiators see no steps; every reading stays inside its sensor's range (requests
/// outside it are clamped, with a note in [`SensorStimulus::notes`]). Each gesture starts
/// with 20 ms at rest, presses in 50 ms, waits 20 ms, strokes, waits 20 ms, releases in
/// 50 ms and rests (200 ms; 300 ms after a pluck, to hear it ring).
///
/// # Errors
///
/// [`SensorStimulusError::Unknown`] for an unknown name; [`SensorStimulusError::NotAPen`]
/// when the program has fewer than two sensors or the depth or stroke sensor is not a length;
/// [`SensorStimulusError::InvalidParameter`] for a speed or stroke that is not finite and
/// positive, a depth or across position that is not finite, or a bad sample rate;
/// [`SensorStimulusError::TooLong`] when a very slow speed makes more than [`MAX_SAMPLES`].
pub fn gesture(
    program: &Program,
    name: &str,
    config: &GestureConfig,
    sample_rate_hz: f64,
) -> Result<SensorStimulus, SensorStimulusError> {
    if !is_gesture(name) {
        return Err(SensorStimulusError::Unknown {
            name: name.to_string(),
        });
    }
    positive("sample_rate_hz", sample_rate_hz)?;
    let not_a_pen = |reason: String| SensorStimulusError::NotAPen {
        gesture: name.to_string(),
        instrument: program.name.clone(),
        reason,
    };
    let sensors = &program.sensors;
    let (iz, ix, iy) = pen_sensors(program);
    if sensors.len() < 2 {
        return Err(not_a_pen(format!(
            "has {} sensor{} ({})",
            sensors.len(),
            if sensors.len() == 1 { "" } else { "s" },
            sensors
                .iter()
                .map(|s| s.name.as_str())
                .collect::<Vec<_>>()
                .join(", ")
        )));
    }
    for s in [&sensors[iz], &sensors[ix]] {
        if s.dim != crate::units::Dim::LENGTH {
            return Err(not_a_pen(format!(
                "has sensor `{}` in {}, not m",
                s.name,
                s.dim.unit_string()
            )));
        }
    }
    let mut notes = Vec::new();
    // Plain millimetres, or scientific notation for a value no key could reach.
    let mm = |x: f64| {
        let v = x * 1e3;
        if v.abs() < 1e9 {
            format!("{v:.3}")
        } else {
            format!("{v:.3e}")
        }
    };
    let (p, r) = (sensors[iz].range, sensors[ix].range);
    let width = r.1 - r.0;
    let depth = match config.depth_m {
        None => p.0 + 0.5 * (p.1 - p.0),
        Some(d) if !d.is_finite() => {
            return Err(SensorStimulusError::InvalidParameter {
                name: "depth",
                value: d,
                expected: "finite",
            })
        }
        Some(d) => {
            let c = d.clamp(p.0, p.1);
            if c != d {
                notes.push(format!(
                    "{name}: depth {} mm is outside sensor `{}`'s range [{}, {}] mm: clamped to {} mm",
                    mm(d),
                    sensors[iz].name,
                    mm(p.0),
                    mm(p.1),
                    mm(c)
                ));
            }
            c
        }
    };
    let speed = config
        .speed_m_per_s
        .unwrap_or(if name == "pluck" { 0.2 } else { 0.1 });
    if !(speed.is_finite() && speed > 0.0) {
        return Err(SensorStimulusError::InvalidParameter {
            name: "speed",
            value: speed,
            expected: "finite and > 0 (m/s)",
        });
    }
    let default_stroke = if name == "bow-stroke" {
        0.6 * width
    } else {
        0.020
    };
    let stroke = match config.stroke_m {
        None => default_stroke,
        Some(l) if !(l.is_finite() && l > 0.0) => {
            return Err(SensorStimulusError::InvalidParameter {
                name: "stroke",
                value: l,
                expected: "finite and > 0 (m)",
            })
        }
        Some(l) => l,
    };
    let stroke = if stroke > width {
        notes.push(format!(
            "{name}: stroke {} mm is longer than sensor `{}`'s range [{}, {}] mm: clamped to {} mm",
            mm(stroke),
            sensors[ix].name,
            mm(r.0),
            mm(r.1),
            mm(width)
        ));
        width
    } else {
        stroke
    };
    let across = match (iy.map(|i| &sensors[i]), config.across_m) {
        (_, Some(a)) if !a.is_finite() => {
            return Err(SensorStimulusError::InvalidParameter {
                name: "across",
                value: a,
                expected: "finite",
            })
        }
        (None, Some(_)) => {
            notes.push(format!(
                "{name}: `{}` has no sensor across the stroke (a third sensor, or a vector sensor's y): the across position is ignored",
                program.name
            ));
            None
        }
        (Some(s), a) => {
            let want = a.unwrap_or(s.range.0);
            let c = want.clamp(s.range.0, s.range.1);
            if c != want {
                notes.push(format!(
                    "{name}: across position {} mm is outside sensor `{}`'s range [{}, {}] mm: clamped to {} mm",
                    mm(want),
                    s.name,
                    mm(s.range.0),
                    mm(s.range.1),
                    mm(c)
                ));
            }
            Some(c)
        }
        (None, None) => None,
    };

    // Stroke ends: inside [r.0, r.1] (stroke <= width; the bounds guard the rounding).
    let middle = r.0 + 0.5 * width;
    let (a, b) = (
        (middle - 0.5 * stroke).max(r.0),
        (middle + 0.5 * stroke).min(r.1),
    );
    let mut pen = Pen {
        t: 0.0,
        press: Track::new(p.0),
        pos: Track::new(a),
    };
    pen.wait(REST_BEFORE_S);
    pen.press_to(depth);
    pen.wait(SETTLE_S);
    let (what, rest_after) = match name {
        "press-rub" => {
            for _ in 0..2 {
                pen.stroke_to(b, speed);
                pen.stroke_to(a, speed);
            }
            ("rubs 2 cycles back and forth between", 0.200)
        }
        "bow-stroke" => {
            pen.stroke_to(b, speed);
            ("bows once from", 0.200)
        }
        _ => {
            pen.stroke_to(b, speed);
            ("plucks across the middle, from", 0.300)
        }
    };
    pen.wait(SETTLE_S);
    pen.press_to(p.0);
    pen.wait(rest_after);

    let samples = (pen.t * sample_rate_hz).round();
    if samples > MAX_SAMPLES as f64 {
        return Err(SensorStimulusError::TooLong {
            source: name.to_string(),
            samples,
        });
    }
    let samples = samples as usize;
    let w = sensors.len();
    let mut values = Vec::with_capacity(samples * w);
    for n in 0..samples {
        let t = n as f64 / sample_rate_hz;
        values.extend(sensors.iter().map(|s| s.range.0));
        values[n * w + iz] = pen.press.at(t);
        values[n * w + ix] = pen.pos.at(t);
        if let (Some(i), Some(c)) = (iy, across) {
            values[n * w + i] = c;
        }
    }
    let description = format!(
        "{name}: the pen presses {} mm into `{}`, {what} {} and {} mm along `{}` at {speed} m/s, and releases",
        mm(depth),
        sensors[iz].name,
        mm(a),
        mm(b),
        sensors[ix].name
    );
    let mut s = SensorStimulus {
        name: name.to_string(),
        description,
        sample_rate_hz,
        sensors: sensors.iter().map(|s| s.name.clone()).collect(),
        samples,
        values,
        notes,
    };
    // A safety net: every move stays between its ends, which are inside the ranges.
    s.clamp_to(program, name);
    Ok(s)
}

/// The sensors a pen gesture drives, as indices into `program.sensors`: (penetration,
/// stroke axis, across). When the program has a vector sensor with components `z` and `x`
/// (the scalar sensors `NAME.z`, `NAME.x` of `sensor NAME: m in { z: …, x: …, y: … }`),
/// they are its `z`, `x` and `y` (`None` without a `y`); otherwise sensors 1, 2 and 3
/// (the third if there is one). Meaningful only for programs with at least two sensors.
pub fn pen_sensors(program: &Program) -> (usize, usize, Option<usize>) {
    let find = |name: &str| program.sensors.iter().position(|s| s.name == name);
    for s in &program.sensors {
        let Some(base) = s.name.strip_suffix(".z") else {
            continue;
        };
        if let (Some(z), Some(x)) = (find(&format!("{base}.z")), find(&format!("{base}.x"))) {
            return (z, x, find(&format!("{base}.y")));
        }
    }
    (0, 1, (program.sensors.len() > 2).then_some(2))
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

/// The largest multi-sensor CSV file [`sensor_csv`] reads, in bytes (it is read whole).
pub const MAX_CSV_BYTES: u64 = 1 << 30;

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
