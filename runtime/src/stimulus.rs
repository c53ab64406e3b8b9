//! Key-position stimuli for a position-driven key.
//!
//! A stimulus is the key travel at the key front, one value per sample, in metres: `0` is
//! the key at rest, positive is pressed down, the full key dip is `dip_m` (≈ 10 mm on a grand
//! piano, DESIGN.md "Reference numbers", from the piano-action literature). The key is
//! *position-driven*: the simulated sensor reads the stimulus exactly, whatever force the
//! instrument pushes back with. So a stimulus is just a `Vec<f64>` and a sample rate; the
//! name and description travel with it into traces and plots.
//!
//! # Motion law
//!
//! Every built-in move from one position to another uses one law: **constant velocity with
//! raised-cosine velocity blends**. Over a blend-in of length `a` the velocity rises as
//! `v/2 · (1 − cos(π t/a))`, it stays at `v` for the middle part, and over a blend-out of
//! length `b` it falls as `v/2 · (1 + cos(π t/b))`. Velocity is continuous and the
//! acceleration is zero at every join, so the position is C² (smooth enough for the
//! `d()`/`d2()` differentiators to see no artificial spikes). With both blends half the move,
//! this is the *cycloidal* law `x(u) = D·(u − sin(2πu)/2π)`, `u = t/T`: peak velocity
//! `2D/T`, twice the mean. Full dips and their releases use the cycloidal law; `half-dip`
//! uses a 1 ms blend-out to model the key hitting a stop; `slow-dip` uses short blends and a
//! long constant-velocity middle.
//!
//! # Built-ins
//!
//! See [`builtin_names`]. Each starts with 20 ms at rest and ends with a rest long enough to
//! see what happens after release (except `hold`, which is still from the first sample to
//! the last, for static tests). Descent times of the full dips: 160 ms (`pp-dip`) and 25 ms
//! (`ff-dip`) are from the literature quoted in DESIGN.md ("key reaches bottom ≈ 25 ms after
//! start at forte, ≈ 160 ms at piano"); the three between are *our* interpolation, equal
//! ratios (≈ 1.59 per level, i.e. log-spaced: 100.6, 63.2, 39.8 ms) rounded to 100, 60 and
//! 40 ms.
//!
//! # CSV format ([`from_csv`])
//!
//! A UTF-8 CSV file with a header row. Lines starting with `#` are comments. Cells may be
//! padded with spaces. The header decides the format:
//!
//! * `key_mm` — one column: key travel in **millimetres**, one row per sample at the
//!   simulation's sample rate;
//! * `time_s,key_mm` — sample time in **seconds** (any spacing, strictly increasing) and key
//!   travel in millimetres. The rows are linearly interpolated onto the sample grid
//!   `t₀ + i/f_s`, `t₀` the first time in the file, up to the last time in the file.
//!
//! ```text
//! # a 10 mm dip, sampled at 1 kHz and resampled to the simulation rate
//! time_s,key_mm
//! 0.000,0
//! 0.050,10
//! 0.350,10
//! 0.400,0
//! ```
//!
//! Every value must be a finite number. Errors name the file, the line and the column.

use std::fmt;
use std::io::{self, Write};
use std::path::{Path, PathBuf};

/// Largest number of samples a stimulus may have (2²⁵ ≈ 33.5 M, 12.7 minutes at 44.1 kHz,
/// 268 MB of f64 per sensor), so that a typo in a sample rate or a time column (a
/// three-line CSV spanning 6000 s) is an error instead of an out-of-memory abort; the trace
/// of a simulation is bounded on its own (`tactus_compiler::sim::MAX_TRACE_VALUES`).
pub const MAX_SAMPLES: usize = 1 << 25;

/// Full key dip of a grand piano key at the key front, metres (≈ 10 mm; DESIGN.md "Reference
/// numbers", piano-action literature).
pub const DEFAULT_DIP_M: f64 = 0.010;

/// Descent times (rest to key bottom, seconds) of the full-dip built-ins, softest first.
/// 160 ms and 25 ms: literature quoted in DESIGN.md; 100, 60, 40 ms: log-spaced
/// interpolation between them, rounded (see the module documentation).
pub const DIP_DESCENT_S: [(&str, f64); 5] = [
    ("pp-dip", 0.160),
    ("p-dip", 0.100),
    ("mf-dip", 0.060),
    ("f-dip", 0.040),
    ("ff-dip", 0.025),
];

/// A key-position stimulus: key travel at the key front, metres per sample.
#[derive(Debug, Clone, PartialEq)]
pub struct Stimulus {
    /// Short name (`"ff-dip"`, or the file name for a CSV stimulus).
    pub name: String,
    /// One line saying what the stimulus does.
    pub description: String,
    /// Sample rate in hertz; sample `i` is at `i / sample_rate_hz` seconds.
    pub sample_rate_hz: f64,
    /// Key travel at the key front, metres; 0 = rest, positive = pressed down.
    pub key: Vec<f64>,
}

impl Stimulus {
    /// Number of samples.
    pub fn len(&self) -> usize {
        self.key.len()
    }

    /// True when the stimulus has no samples.
    pub fn is_empty(&self) -> bool {
        self.key.is_empty()
    }

    /// Duration in seconds: number of samples divided by the sample rate.
    pub fn duration_s(&self) -> f64 {
        self.key.len() as f64 / self.sample_rate_hz
    }

    /// Key velocity in m/s (positive = going down), one value per sample: central differences
    /// inside, one-sided differences at both ends, 0 for a single sample. For checking
    /// stimuli; the engines use the multi-sample differentiators of
    /// [`differentiator`](crate::differentiator).
    pub fn velocity_m_per_s(&self) -> Vec<f64> {
        let x = &self.key;
        let fs = self.sample_rate_hz;
        let n = x.len();
        (0..n)
            .map(|i| match (i.checked_sub(1), (i + 1 < n).then_some(i + 1)) {
                (Some(p), Some(q)) => (x[q] - x[p]) * fs / 2.0,
                (Some(p), None) => (x[i] - x[p]) * fs,
                (None, Some(q)) => (x[q] - x[i]) * fs,
                (None, None) => 0.0,
            })
            .collect()
    }

    /// Writes the stimulus in the one-column `key_mm` CSV format that [`from_csv`] reads,
    /// after two `#` comment lines giving its name, description and sample rate (the sample
    /// rate is information only; [`from_csv`] takes it as an argument).
    ///
    /// # Errors
    ///
    /// Whatever the writer returns.
    pub fn write_csv<W: Write>(&self, mut w: W) -> io::Result<()> {
        writeln!(w, "# {}: {}", self.name, self.description)?;
        writeln!(w, "# sampled at {} Hz", self.sample_rate_hz)?;
        writeln!(w, "key_mm")?;
        for &x in &self.key {
            writeln!(w, "{}", x * 1e3)?;
        }
        w.flush()
    }
}

/// Why a stimulus could not be made or read.
#[derive(Debug)]
pub enum StimulusError {
    /// [`builtin`] was asked for a name it does not know.
    UnknownBuiltin {
        /// The name asked for.
        name: String,
    },
    /// A numeric argument is out of its valid range.
    InvalidParameter {
        /// The argument's name (`"dip_m"`, `"sample_rate_hz"`, …).
        name: &'static str,
        /// The value given.
        value: f64,
        /// What it must be (`"finite and > 0"`).
        expected: &'static str,
    },
    /// The stimulus would have more than [`MAX_SAMPLES`] samples.
    TooLong {
        /// Where the stimulus came from (built-in name or file).
        source: String,
        /// Number of samples it would have.
        samples: f64,
    },
    /// A CSV file could not be opened or read.
    Io {
        /// The file.
        path: PathBuf,
        /// What the operating system said.
        source: io::Error,
    },
    /// A CSV file is malformed (e.g. rows with different numbers of cells).
    Csv {
        /// The file.
        path: PathBuf,
        /// The line, when known (1-based).
        line: Option<u64>,
        /// What the CSV reader said.
        message: String,
    },
    /// The header row is not one of the accepted headers.
    Header {
        /// The file.
        path: PathBuf,
        /// The header row as found.
        header: String,
    },
    /// A cell is not a finite number.
    Cell {
        /// The file.
        path: PathBuf,
        /// The line (1-based).
        line: u64,
        /// The column's header.
        column: &'static str,
        /// The cell's text.
        text: String,
    },
    /// In the `time_s,key_mm` format, a time is not greater than the one before.
    NotIncreasing {
        /// The file.
        path: PathBuf,
        /// The line (1-based).
        line: u64,
        /// The previous time, seconds.
        previous_s: f64,
        /// This line's time, seconds.
        time_s: f64,
    },
    /// The file has no header or no samples.
    Empty {
        /// The file.
        path: PathBuf,
        /// What is missing (`"header row"` or `"samples"`).
        missing: &'static str,
    },
}

impl fmt::Display for StimulusError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            StimulusError::UnknownBuiltin { name } => {
                write!(f, "unknown stimulus `{name}`; the built-in stimuli are: ")?;
                let names: Vec<&str> = BUILTINS.iter().map(|(n, _)| *n).collect();
                write!(f, "{}", names.join(", "))
            }
            StimulusError::InvalidParameter {
                name,
                value,
                expected,
            } => write!(
                f,
                "stimulus parameter `{name}` = {value}: must be {expected}"
            ),
            StimulusError::TooLong { source, samples } => write!(
                f,
                "stimulus `{source}` would have {} samples, more than the limit of \
                 {MAX_SAMPLES} (check the sample rate and the times)",
                if *samples < 1e15 {
                    format!("{samples:.0}")
                } else {
                    format!("{samples:.3e}")
                }
            ),
            StimulusError::Io { path, source } => {
                write!(f, "{}: cannot read stimulus: {source}", path.display())
            }
            StimulusError::Csv {
                path,
                line,
                message,
            } => match line {
                Some(line) => write!(f, "{}:{line}: malformed CSV: {message}", path.display()),
                None => write!(f, "{}: malformed CSV: {message}", path.display()),
            },
            StimulusError::Header { path, header } => write!(
                f,
                "{}:1: unknown stimulus header `{header}`; expected `key_mm` (one key \
                 position in mm per sample) or `time_s,key_mm` (times in s, positions in mm)",
                path.display()
            ),
            StimulusError::Cell {
                path,
                line,
                column,
                text,
            } => write!(
                f,
                "{}:{line}: column `{column}`: `{text}` is not a finite number",
                path.display()
            ),
            StimulusError::NotIncreasing {
                path,
                line,
                previous_s,
                time_s,
            } => write!(
                f,
                "{}:{line}: column `time_s`: {time_s} s is not after the previous time \
                 {previous_s} s (times must be strictly increasing)",
                path.display()
            ),
            StimulusError::Empty { path, missing } => {
                write!(f, "{}: empty stimulus file: no {missing}", path.display())
            }
        }
    }
}

impl std::error::Error for StimulusError {
    fn source(&self) -> Option<&(dyn std::error::Error + 'static)> {
        match self {
            StimulusError::Io { source, .. } => Some(source),
            _ => None,
        }
    }
}

/// The built-in stimuli: (name, one-line description). Keep in step with [`builtin`].
const BUILTINS: &[(&str, &str)] = &[
    (
        "pp-dip",
        "full dip, pianissimo: 160 ms descent, 300 ms hold, 60 ms release",
    ),
    (
        "p-dip",
        "full dip, piano: 100 ms descent, 300 ms hold, 60 ms release",
    ),
    (
        "mf-dip",
        "full dip, mezzo-forte: 60 ms descent, 300 ms hold, 60 ms release",
    ),
    (
        "f-dip",
        "full dip, forte: 40 ms descent, 300 ms hold, 60 ms release",
    ),
    (
        "ff-dip",
        "full dip, fortissimo: 25 ms descent, 300 ms hold, 60 ms release",
    ),
    (
        "half-dip",
        "press to 50% of the dip in 20 ms onto a stop (stops within 1 ms), hold 400 ms, \
         release slowly",
    ),
    (
        "repeated",
        "four notes at 8 notes/s: 40 ms presses, partial releases to 30% of the dip, \
         last one released fully",
    ),
    (
        "slow-dip",
        "quasi-static dip at constant speed: 2 s down, 2 s up (force-vs-position curves)",
    ),
    (
        "hold",
        "key held still at 50% of the dip for 200 ms, from the first sample (static tests)",
    ),
];

/// The built-in stimuli as (name, one-line description), in a stable order, for `--help`.
pub fn builtin_names() -> &'static [(&'static str, &'static str)] {
    BUILTINS
}

/// Parameters of a full key dip and release (the `*-dip` built-ins); all times in seconds.
/// The press and the release follow the cycloidal law (see the module documentation).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DipConfig {
    /// Full key dip at the key front, metres (default 0.010: DESIGN.md "Reference numbers").
    pub dip_m: f64,
    /// Rest before the press, seconds (default 0.020).
    pub rest_before_s: f64,
    /// Descent time, rest to key bottom, seconds (default 0.060, `mf-dip`).
    pub descent_s: f64,
    /// Time held at the bottom, seconds (default 0.300).
    pub hold_s: f64,
    /// Release time, bottom to rest, seconds (default 0.060).
    pub release_s: f64,
    /// Rest after the release, seconds (default 0.400, enough to see the hammer land on the
    /// rest felt and the key rebound).
    pub rest_after_s: f64,
}

impl Default for DipConfig {
    fn default() -> Self {
        DipConfig {
            dip_m: DEFAULT_DIP_M,
            rest_before_s: 0.020,
            descent_s: 0.060,
            hold_s: 0.300,
            release_s: 0.060,
            rest_after_s: 0.400,
        }
    }
}

impl DipConfig {
    /// The stimulus for this dip, sampled at `sample_rate_hz`, named `name`.
    ///
    /// # Errors
    ///
    /// [`StimulusError::InvalidParameter`] when the dip, the descent or release time or the
    /// sample rate is not finite and positive, or a rest or hold time is negative or not
    /// finite; [`StimulusError::TooLong`] when it would exceed [`MAX_SAMPLES`].
    pub fn stimulus(&self, name: &str, sample_rate_hz: f64) -> Result<Stimulus, StimulusError> {
        positive("dip_m", self.dip_m)?;
        positive("descent_s", self.descent_s)?;
        positive("release_s", self.release_s)?;
        non_negative("rest_before_s", self.rest_before_s)?;
        non_negative("hold_s", self.hold_s)?;
        non_negative("rest_after_s", self.rest_after_s)?;
        let d = self.dip_m;
        let mut p = Profile::new(d);
        p.rest(self.rest_before_s);
        p.cycloid(d, self.descent_s);
        p.rest(self.hold_s);
        p.cycloid(0.0, self.release_s);
        p.rest(self.rest_after_s);
        let description = format!(
            "full dip to {} mm: {} ms descent, {} ms hold, {} ms release",
            d * 1e3,
            self.descent_s * 1e3,
            self.hold_s * 1e3,
            self.release_s * 1e3
        );
        p.sample(name, description, sample_rate_hz)
    }
}

/// A full dip of `dip_m` metres: 20 ms at rest, a cycloidal descent of `descent_s` seconds,
/// `hold_s` at the bottom, a cycloidal release of `release_s`, 400 ms at rest. The general
/// form of the `*-dip` built-ins, for sweeping key speeds; see [`DipConfig`] for every
/// parameter.
///
/// # Errors
///
/// As [`DipConfig::stimulus`].
pub fn dip(
    descent_s: f64,
    hold_s: f64,
    release_s: f64,
    dip_m: f64,
    sample_rate_hz: f64,
) -> Result<Stimulus, StimulusError> {
    DipConfig {
        dip_m,
        descent_s,
        hold_s,
        release_s,
        ..DipConfig::default()
    }
    .stimulus("dip", sample_rate_hz)
}

/// The built-in stimulus `name` (see [`builtin_names`]) for a key dip of `dip_m` metres,
/// sampled at `sample_rate_hz`.
///
/// # Errors
///
/// [`StimulusError::UnknownBuiltin`] (its message lists the valid names),
/// [`StimulusError::InvalidParameter`] when `dip_m` or `sample_rate_hz` is not finite and
/// positive, [`StimulusError::TooLong`] for absurd sample rates.
pub fn builtin(name: &str, dip_m: f64, sample_rate_hz: f64) -> Result<Stimulus, StimulusError> {
    positive("dip_m", dip_m)?;
    positive("sample_rate_hz", sample_rate_hz)?;
    let Some(&(name, description)) = BUILTINS.iter().find(|(n, _)| *n == name) else {
        return Err(StimulusError::UnknownBuiltin {
            name: name.to_string(),
        });
    };
    if let Some(&(_, descent_s)) = DIP_DESCENT_S.iter().find(|(n, _)| *n == name) {
        let mut s = DipConfig {
            dip_m,
            descent_s,
            ..DipConfig::default()
        }
        .stimulus(name, sample_rate_hz)?;
        s.description = description.to_string();
        return Ok(s);
    }
    let d = dip_m;
    let mut p = Profile::new(d);
    match name {
        "half-dip" => {
            // Press to 50 % in 20 ms: 5 ms blend-in, constant speed, and a 1 ms blend-out
            // for the key hitting a stop (peak speed 0.5·dip / 17 ms ≈ 0.29 m/s for a 10 mm
            // dip, about the peak speed of `mf-dip`).
            p.rest(0.020);
            p.move_to(0.5 * d, 0.020, 0.005, 0.001);
            p.rest(0.400);
            p.cycloid(0.0, 0.250);
            p.rest(0.400);
        }
        "repeated" => {
            // Period 125 ms = 8 notes/s: press 40 ms, 35 ms at the bottom, 35 ms partial
            // release to 30 %, 15 ms there before the next press.
            p.rest(0.020);
            for note in 0..4 {
                p.cycloid(d, 0.040);
                p.rest(0.035);
                if note < 3 {
                    p.cycloid(0.3 * d, 0.035);
                    p.rest(0.015);
                }
            }
            p.cycloid(0.0, 0.060);
            p.rest(0.400);
        }
        "slow-dip" => {
            // 2 s each way with 50 ms blends: constant speed dip/1.95 s (≈ 5 mm/s for 10 mm)
            // over 95 % of the travel, so the viscous terms are constant there.
            p.rest(0.020);
            p.move_to(d, 2.0, 0.050, 0.050);
            p.rest(0.100);
            p.move_to(0.0, 2.0, 0.050, 0.050);
            p.rest(0.200);
        }
        "hold" => {
            p.position = 0.5 * d;
            p.rest(0.200);
        }
        _ => {
            // Every name in BUILTINS is handled above; a new one without a case lands here.
            return Err(StimulusError::UnknownBuiltin {
                name: name.to_string(),
            });
        }
    }
    p.sample(name, description.to_string(), sample_rate_hz)
}

/// Reads a stimulus from a CSV file (format in the module documentation) and samples it at
/// `sample_rate_hz`. Positions are converted from millimetres to metres. The stimulus is
/// named after the file's stem.
///
/// # Errors
///
/// [`StimulusError::Io`] when the file cannot be read; [`StimulusError::Empty`] without a
/// header or samples; [`StimulusError::Header`] for an unknown header;
/// [`StimulusError::Cell`] for a cell that is not a finite number;
/// [`StimulusError::NotIncreasing`] for times out of order; [`StimulusError::Csv`] for
/// malformed CSV; [`StimulusError::InvalidParameter`] for a bad sample rate;
/// [`StimulusError::TooLong`] for more than [`MAX_SAMPLES`] samples. Every error names the
/// file, and the line and column where there is one.
pub fn from_csv(path: &Path, sample_rate_hz: f64) -> Result<Stimulus, StimulusError> {
    positive("sample_rate_hz", sample_rate_hz)?;
    let csv_err = |e: csv::Error| {
        let line = e.position().map(|p| p.line());
        let message = e.to_string();
        match e.into_kind() {
            csv::ErrorKind::Io(source) => StimulusError::Io {
                path: path.to_path_buf(),
                source,
            },
            _ => StimulusError::Csv {
                path: path.to_path_buf(),
                line,
                message,
            },
        }
    };
    let file = std::fs::File::open(path).map_err(|source| StimulusError::Io {
        path: path.to_path_buf(),
        source,
    })?;
    let mut reader = csv::ReaderBuilder::new()
        .has_headers(true)
        .comment(Some(b'#'))
        .trim(csv::Trim::All)
        .from_reader(io::BufReader::new(file));
    let header: Vec<String> = reader
        .headers()
        .map_err(csv_err)?
        .iter()
        .map(str::to_string)
        .collect();
    let timed = match header.iter().map(String::as_str).collect::<Vec<_>>()[..] {
        [] | [""] => {
            return Err(StimulusError::Empty {
                path: path.to_path_buf(),
                missing: "header row",
            })
        }
        ["key_mm"] => false,
        ["time_s", "key_mm"] => true,
        _ => {
            return Err(StimulusError::Header {
                path: path.to_path_buf(),
                header: header.join(","),
            })
        }
    };
    let columns: &[&'static str] = if timed {
        &["time_s", "key_mm"]
    } else {
        &["key_mm"]
    };
    let mut times = Vec::new();
    let mut keys = Vec::new();
    let mut record = csv::StringRecord::new();
    while reader.read_record(&mut record).map_err(csv_err)? {
        let line = record.position().map_or(0, |p| p.line());
        let mut values = [0.0; 2];
        for (i, column) in columns.iter().enumerate() {
            let text = record.get(i).unwrap_or("");
            values[i] = match text.parse::<f64>() {
                Ok(v) if v.is_finite() => v,
                _ => {
                    return Err(StimulusError::Cell {
                        path: path.to_path_buf(),
                        line,
                        column,
                        text: text.to_string(),
                    })
                }
            };
        }
        if timed {
            let [t, key_mm] = values;
            if let Some(&previous_s) = times.last() {
                if t <= previous_s {
                    return Err(StimulusError::NotIncreasing {
                        path: path.to_path_buf(),
                        line,
                        previous_s,
                        time_s: t,
                    });
                }
            }
            times.push(t);
            keys.push(key_mm * 1e-3);
        } else {
            keys.push(values[0] * 1e-3);
        }
        if keys.len() > MAX_SAMPLES {
            return Err(StimulusError::TooLong {
                source: path.display().to_string(),
                samples: keys.len() as f64,
            });
        }
    }
    if keys.is_empty() {
        return Err(StimulusError::Empty {
            path: path.to_path_buf(),
            missing: "samples",
        });
    }
    let key = if timed {
        resample(&times, &keys, sample_rate_hz, path)?
    } else {
        keys
    };
    let name = path.file_stem().map_or_else(
        || path.display().to_string(),
        |s| s.to_string_lossy().into(),
    );
    let description = if timed {
        format!(
            "key positions from {} (time_s,key_mm, resampled)",
            path.display()
        )
    } else {
        format!("key positions from {} (key_mm per sample)", path.display())
    };
    Ok(Stimulus {
        name,
        description,
        sample_rate_hz,
        key,
    })
}

/// Linear interpolation of `(times, keys)` (times strictly increasing, at least one) onto
/// `times[0] + i / sample_rate_hz` up to `times.last()`.
fn resample(
    times: &[f64],
    keys: &[f64],
    sample_rate_hz: f64,
    path: &Path,
) -> Result<Vec<f64>, StimulusError> {
    let t0 = times[0];
    let span = times[times.len() - 1] - t0;
    let samples = (span * sample_rate_hz).floor() + 1.0;
    if !samples.is_finite() || samples > MAX_SAMPLES as f64 {
        return Err(StimulusError::TooLong {
            source: path.display().to_string(),
            samples,
        });
    }
    let n = samples as usize;
    let mut out = Vec::with_capacity(n);
    let mut j = 0; // times[j] <= t < times[j + 1]
    for i in 0..n {
        let t = t0 + i as f64 / sample_rate_hz;
        while j + 2 < times.len() && times[j + 1] <= t {
            j += 1;
        }
        let x = if j + 1 < times.len() {
            let (ta, tb) = (times[j], times[j + 1]);
            let u = ((t - ta) / (tb - ta)).clamp(0.0, 1.0);
            keys[j] + (keys[j + 1] - keys[j]) * u
        } else {
            keys[j]
        };
        out.push(x);
    }
    Ok(out)
}

fn positive(name: &'static str, value: f64) -> Result<(), StimulusError> {
    if value.is_finite() && value > 0.0 {
        Ok(())
    } else {
        Err(StimulusError::InvalidParameter {
            name,
            value,
            expected: "finite and > 0",
        })
    }
}

fn non_negative(name: &'static str, value: f64) -> Result<(), StimulusError> {
    if value.is_finite() && value >= 0.0 {
        Ok(())
    } else {
        Err(StimulusError::InvalidParameter {
            name,
            value,
            expected: "finite and >= 0",
        })
    }
}

/// One piece of a key trajectory, starting at `start_s`.
#[derive(Debug, Clone, Copy)]
struct Segment {
    start_s: f64,
    duration_s: f64,
    from: f64,
    to: f64,
    blend_in_s: f64,
    blend_out_s: f64,
}

impl Segment {
    /// Position at `t` seconds into the segment (clamped to the segment).
    fn position(&self, t: f64) -> f64 {
        let (dur, a, b) = (self.duration_s, self.blend_in_s, self.blend_out_s);
        if dur <= 0.0 || self.from == self.to {
            return self.to;
        }
        let t = t.clamp(0.0, dur);
        let c = dur - a - b; // constant-velocity part
        let v = 1.0 / (0.5 * a + c + 0.5 * b); // normalised peak velocity: travel 1
        let pi = std::f64::consts::PI;
        let f = if t < a {
            0.5 * v * (t - a / pi * (pi * t / a).sin())
        } else if t < a + c {
            v * (0.5 * a + (t - a))
        } else {
            let u = t - a - c;
            v * (0.5 * a + c) + 0.5 * v * (u + b / pi * (pi * u / b).sin())
        };
        let f = f.clamp(0.0, 1.0);
        self.from + (self.to - self.from) * f
    }
}

/// A key trajectory under construction: segments end to end from `position` at 0 s.
struct Profile {
    dip_m: f64,
    position: f64,
    end_s: f64,
    segments: Vec<Segment>,
}

impl Profile {
    fn new(dip_m: f64) -> Self {
        Profile {
            dip_m,
            position: 0.0,
            end_s: 0.0,
            segments: Vec::new(),
        }
    }

    /// Moves to `to` in `duration_s` with the given blends (their sum ≤ the duration).
    fn move_to(&mut self, to: f64, duration_s: f64, blend_in_s: f64, blend_out_s: f64) {
        let scale = if blend_in_s + blend_out_s > duration_s {
            duration_s / (blend_in_s + blend_out_s)
        } else {
            1.0
        };
        self.segments.push(Segment {
            start_s: self.end_s,
            duration_s,
            from: self.position,
            to,
            blend_in_s: blend_in_s * scale,
            blend_out_s: blend_out_s * scale,
        });
        self.end_s += duration_s;
        self.position = to;
    }

    /// Cycloidal move (raised-cosine velocity over the whole move) to `to`.
    fn cycloid(&mut self, to: f64, duration_s: f64) {
        self.move_to(to, duration_s, 0.5 * duration_s, 0.5 * duration_s);
    }

    /// Stays where the key is.
    fn rest(&mut self, duration_s: f64) {
        self.move_to(self.position, duration_s, 0.0, 0.0);
    }

    /// Samples `[0, end]` at `sample_rate_hz`: `floor(end · f_s) + 1` samples, clamped to
    /// `[0, dip]` against rounding.
    fn sample(
        &self,
        name: &str,
        description: String,
        sample_rate_hz: f64,
    ) -> Result<Stimulus, StimulusError> {
        positive("sample_rate_hz", sample_rate_hz)?;
        let samples = (self.end_s * sample_rate_hz).floor() + 1.0;
        if !samples.is_finite() || samples > MAX_SAMPLES as f64 {
            return Err(StimulusError::TooLong {
                source: name.to_string(),
                samples,
            });
        }
        let n = samples as usize;
        let mut key = Vec::with_capacity(n);
        let mut k = 0;
        for i in 0..n {
            let t = i as f64 / sample_rate_hz;
            while k + 1 < self.segments.len() && self.segments[k + 1].start_s <= t {
                k += 1;
            }
            let x = match self.segments.get(k) {
                Some(s) => s.position(t - s.start_s),
                None => self.position,
            };
            key.push(x.clamp(0.0, self.dip_m));
        }
        Ok(Stimulus {
            name: name.to_string(),
            description,
            sample_rate_hz,
            key,
        })
    }
}
