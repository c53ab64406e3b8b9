//! The stimulus of every sensor of a program ([`SensorStimulus`]) and the multi-sensor CSV
//! reader ([`sensor_csv`]).
//!
//! A [`SensorStimulus`] gives every sensor of a program a position per sample (SI). It is
//! made from
//!
//! * a **key stimulus** ([`tactus_runtime::stimulus::Stimulus`], built-in or the
//!   `key_mm`/`time_s,key_mm` CSV): the key travel drives the program's *first* sensor and
//!   every other sensor reads its lower bound ([`SensorStimulus::from_key`]);
//! * a **multi-sensor CSV** naming the sensors in its header ([`sensor_csv`]);
//! * a built-in **pen gesture** for contact-point instruments ([`super::gesture`], names in
//!   [`super::gesture_names`]): the pen's penetration into the surface or string, its position
//!   along the rubbing/bowing/plucking axis and, optionally, its position across (e.g. which
//!   string). An instrument with a vector sensor (`sensor pen: m in { z: …, x: …, y: … }`)
//!   gets them on its components `z`, `x` and `y` ([`super::pen_sensors`]); otherwise sensor 1 is
//!   the penetration, sensor 2 the stroke axis and sensor 3 across. The convention follows
//!   the 3-DoF pen of Onofrei, Fontana & Serafin 2023 (plucking, bowing and rubbing
//!   physically-based resonators).
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

use super::GESTURES;
use super::MAX_TRACE_VALUES;
use crate::ir::Program;
use std::fmt;
use std::path::{Path, PathBuf};
use tactus_runtime::stimulus::{self, Stimulus, StimulusError, MAX_SAMPLES};

/// The largest multi-sensor CSV file [`sensor_csv`] reads, in bytes (it is read whole).
pub const MAX_CSV_BYTES: u64 = 1 << 30;

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
    /// it), so [`super::simulate_sensors`] on the result is exactly [`super::simulate`] on `key`.
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
    pub(super) fn clamp_to(&mut self, program: &Program, what: &str) {
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

pub(super) fn positive(name: &'static str, value: f64) -> Result<(), SensorStimulusError> {
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
