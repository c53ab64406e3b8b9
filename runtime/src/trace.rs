//! Traces of a simulation: one named, unit-tagged column of `f64` per quantity, one row per
//! sample.
//!
//! A trace is stored column-major because every consumer reads it that way: a plot draws one
//! column against another, a test compares one column of two engines, and a CSV writer walks
//! the columns of a row. Each column carries a [`ColumnKind`] so that tools can group the
//! columns without knowing the instrument: the plotter draws every [`ColumnKind::Force`] term
//! and the [`ColumnKind::TotalForce`] on one panel, against time and against the first
//! [`ColumnKind::Sensor`].
//!
//! Values are SI (metres, seconds, newtons, …) and the column's `unit` names the unit. Two
//! conventions keep everything in `f64`:
//!
//! * an **event** column holds `NaN` on samples where the event did not fire and a value
//!   (e.g. the impact velocity, or `1.0`) on samples where it fired; CSV writes `NaN` as an
//!   empty cell;
//! * a **mode** column holds the index of the active variant (0, 1, …) as `f64`.
//!
//! # Invariant
//!
//! Every column has the same number of values. [`Trace::add_column`] and [`Trace::push_row`]
//! keep it; code that edits the public fields directly must keep it too. Readers do not panic
//! when it is broken: [`Trace::len`] is the length of the shortest column and only that many
//! rows are written.

use std::fmt;
use std::fs::File;
use std::io::{self, BufWriter, Write};
use std::path::{Path, PathBuf};

/// What a trace column holds. Decides how the CSV groups it and which plot it goes on.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum ColumnKind {
    /// Simulation time, seconds.
    Time,
    /// A sensor input (e.g. key position at the key front, metres).
    Sensor,
    /// One named force term of the touch profile, newtons.
    Force,
    /// The sum of all force terms: the force commanded to the motor, newtons.
    TotalForce,
    /// A continuous state (e.g. hammer position, metres; hammer velocity, m/s).
    State,
    /// An enumerated mode; the value is the index of the active variant.
    Mode,
    /// A named output of the instrument (e.g. hammer velocity for a synthesizer).
    Output,
    /// An event: `NaN` where it did not fire, a value where it fired.
    Event,
}

impl ColumnKind {
    /// The kind's name as written in the language and in reports (`"force"`, `"event"`, …).
    pub fn as_str(self) -> &'static str {
        match self {
            ColumnKind::Time => "time",
            ColumnKind::Sensor => "sensor",
            ColumnKind::Force => "force",
            ColumnKind::TotalForce => "total force",
            ColumnKind::State => "state",
            ColumnKind::Mode => "mode",
            ColumnKind::Output => "output",
            ColumnKind::Event => "event",
        }
    }
}

impl fmt::Display for ColumnKind {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.as_str())
    }
}

/// One traced quantity: its name, its SI unit, its kind and one value per sample.
#[derive(Debug, Clone, PartialEq)]
pub struct Column {
    /// Name as in the touch profile (`"escapement"`, `"key"`, `"hammer.v"`).
    pub name: String,
    /// SI unit symbol (`"N"`, `"m"`, `"m/s"`); empty for dimensionless values.
    pub unit: String,
    /// What the column holds.
    pub kind: ColumnKind,
    /// One value per sample, in SI units; `NaN` where an event did not fire.
    pub values: Vec<f64>,
}

impl Column {
    /// The CSV header cell: `name [unit]`, or just `name` when the unit is empty.
    pub fn header(&self) -> String {
        if self.unit.is_empty() {
            self.name.clone()
        } else {
            format!("{} [{}]", self.name, self.unit)
        }
    }
}

/// A simulation trace: columns of equal length sampled at `sample_rate_hz`.
#[derive(Debug, Clone, PartialEq)]
pub struct Trace {
    /// Sample rate in hertz (the board's default is
    /// [`DEFAULT_SAMPLE_RATE_HZ`](crate::DEFAULT_SAMPLE_RATE_HZ), 44.1 kHz).
    pub sample_rate_hz: f64,
    /// The columns, in the order they are written.
    pub columns: Vec<Column>,
}

/// Why a trace could not be built or written.
#[derive(Debug)]
pub enum TraceError {
    /// [`Trace::push_row`] got a row whose length is not the number of columns.
    RowLength {
        /// Zero-based index of the row that was being pushed.
        row: usize,
        /// Number of columns in the trace.
        expected: usize,
        /// Number of values given.
        got: usize,
    },
    /// Creating or writing a file failed.
    Io {
        /// The file.
        path: PathBuf,
        /// What the operating system said.
        source: io::Error,
    },
}

impl fmt::Display for TraceError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            TraceError::RowLength { row, expected, got } => write!(
                f,
                "trace row {row}: got {got} values but the trace has {expected} columns \
                 (one value per column, in column order)"
            ),
            TraceError::Io { path, source } => {
                write!(f, "{}: cannot write trace: {source}", path.display())
            }
        }
    }
}

impl std::error::Error for TraceError {
    fn source(&self) -> Option<&(dyn std::error::Error + 'static)> {
        match self {
            TraceError::RowLength { .. } => None,
            TraceError::Io { source, .. } => Some(source),
        }
    }
}

impl Trace {
    /// An empty trace (no columns, no rows) sampled at `sample_rate_hz` hertz.
    pub fn new(sample_rate_hz: f64) -> Self {
        Trace {
            sample_rate_hz,
            columns: Vec::new(),
        }
    }

    /// Adds a column and returns its index. If rows were already pushed, the new column is
    /// filled with `NaN` for them so that every column keeps the same length.
    pub fn add_column(
        &mut self,
        name: impl Into<String>,
        unit: impl Into<String>,
        kind: ColumnKind,
    ) -> usize {
        let rows = self.len();
        self.columns.push(Column {
            name: name.into(),
            unit: unit.into(),
            kind,
            values: vec![f64::NAN; rows],
        });
        self.columns.len() - 1
    }

    /// Appends one sample: `values[i]` goes to column `i`.
    ///
    /// # Errors
    ///
    /// [`TraceError::RowLength`] when `values.len()` is not the number of columns; the trace
    /// is left unchanged.
    pub fn push_row(&mut self, values: &[f64]) -> Result<(), TraceError> {
        if values.len() != self.columns.len() {
            return Err(TraceError::RowLength {
                row: self.len(),
                expected: self.columns.len(),
                got: values.len(),
            });
        }
        for (column, &value) in self.columns.iter_mut().zip(values) {
            column.values.push(value);
        }
        Ok(())
    }

    /// Number of rows (samples): the length of the shortest column, 0 without columns.
    pub fn len(&self) -> usize {
        self.columns
            .iter()
            .map(|c| c.values.len())
            .min()
            .unwrap_or(0)
    }

    /// True when the trace has no rows.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// The first column called `name`.
    pub fn column(&self, name: &str) -> Option<&Column> {
        self.columns.iter().find(|c| c.name == name)
    }

    /// The index of the first column called `name`.
    pub fn column_index(&self, name: &str) -> Option<usize> {
        self.columns.iter().position(|c| c.name == name)
    }

    /// The columns of one kind, in column order.
    pub fn columns_of(&self, kind: ColumnKind) -> impl Iterator<Item = &Column> + '_ {
        self.columns.iter().filter(move |c| c.kind == kind)
    }

    /// Time of every row in seconds: the first [`ColumnKind::Time`] column when there is one,
    /// otherwise `row / sample_rate_hz`.
    pub fn times_s(&self) -> Vec<f64> {
        let rows = self.len();
        match self.columns_of(ColumnKind::Time).next() {
            Some(time) => time.values[..rows].to_vec(),
            None => (0..rows).map(|i| i as f64 / self.sample_rate_hz).collect(),
        }
    }

    /// Writes the trace as CSV: a header row of [`Column::header`] cells, then one row per
    /// sample. Values are written with Rust's shortest round-trip formatting (`{}` of `f64`,
    /// so reading them back gives the same bits); `NaN` is written as an empty cell.
    ///
    /// # Errors
    ///
    /// Whatever the writer returns.
    pub fn write_csv<W: Write>(&self, w: W) -> io::Result<()> {
        let mut out = csv::Writer::from_writer(w);
        out.write_record(self.columns.iter().map(Column::header))?;
        let mut cells: Vec<String> = Vec::with_capacity(self.columns.len());
        for row in 0..self.len() {
            cells.clear();
            cells.extend(self.columns.iter().map(|c| {
                let v = c.values[row];
                if v.is_nan() {
                    String::new()
                } else {
                    v.to_string()
                }
            }));
            out.write_record(&cells)?;
        }
        out.flush()
    }

    /// Writes the trace as CSV (see [`Trace::write_csv`]) to the file at `path`, creating or
    /// truncating it.
    ///
    /// # Errors
    ///
    /// [`TraceError::Io`] naming `path` when the file cannot be created or written.
    pub fn write_csv_file(&self, path: &Path) -> Result<(), TraceError> {
        let io_err = |source| TraceError::Io {
            path: path.to_path_buf(),
            source,
        };
        let file = File::create(path).map_err(io_err)?;
        let mut w = BufWriter::new(file);
        self.write_csv(&mut w).map_err(io_err)?;
        w.flush().map_err(io_err)
    }
}
