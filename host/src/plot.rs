//! SVG plots of simulation traces.
//!
//! Plots are for a person looking at a touch profile, so they use the units an instrument
//! maker reads: time in milliseconds, key travel in millimetres, force in newtons. The trace
//! stays in SI; [`display_unit`] converts on the way to the page. Which columns go on which
//! plot is decided by their [`ColumnKind`], so the plotter needs no knowledge of the
//! instrument.
//!
//! A second of trace at 44.1 kHz is 44 100 points per series; drawn as-is that makes SVGs of
//! many megabytes that no one can open. Each series is reduced to at most
//! [`MAX_POINTS_PER_SERIES`] points by keeping the minimum and the maximum of each run of
//! samples, so impact pulses and escapement peaks one sample wide still show. `NaN` values
//! (events that did not fire, missing samples) are skipped: lines break at them.
//!
//! Text is written as SVG `<text>` elements (plotters' SVG backend without the `ttf`
//! feature); the viewer picks the font, so no system fonts are needed to write a plot.

use std::fmt;
use std::ops::Range;
use std::path::{Path, PathBuf};

use plotters::coord::ranged1d::ValueFormatter;
use plotters::coord::Shift;
use plotters::prelude::*;
use tactus_runtime::trace::{Column, ColumnKind, Trace};

/// Width of every plot, pixels.
const WIDTH: u32 = 1100;
/// Line colours, cycled (Tableau 10, minus grey: distinct on white and for most colour-blind
/// readers); the total force is always black.
const COLOURS: [RGBColor; 9] = [
    RGBColor(31, 119, 180),
    RGBColor(255, 127, 14),
    RGBColor(44, 160, 44),
    RGBColor(214, 39, 40),
    RGBColor(148, 103, 189),
    RGBColor(140, 86, 75),
    RGBColor(227, 119, 194),
    RGBColor(188, 189, 34),
    RGBColor(23, 190, 207),
];

fn colour(i: usize) -> RGBAColor {
    COLOURS[i % COLOURS.len()].to_rgba()
}

/// A legend label padded with spaces: without font files plotters estimates text width at
/// about 0.45 em per character, narrower than real sans-serif text, and sizes the legend box
/// from that estimate. The trailing spaces widen the box; SVG viewers do not draw them.
fn legend_label(label: &str) -> String {
    let pad = label.chars().count() / 3 + 1;
    format!("{label}{}", " ".repeat(pad))
}

/// Most points drawn per series (min/max decimation above it).
pub const MAX_POINTS_PER_SERIES: usize = 4000;

/// Why a plot could not be written.
#[derive(Debug)]
pub enum PlotError {
    /// The trace has no rows.
    EmptyTrace {
        /// The SVG file that was to be written.
        path: PathBuf,
    },
    /// The trace has no [`ColumnKind::Force`] or [`ColumnKind::TotalForce`] column.
    NoForces {
        /// The SVG file that was to be written.
        path: PathBuf,
    },
    /// No column names were given to [`plot_columns`].
    NoColumns {
        /// The SVG file that was to be written.
        path: PathBuf,
    },
    /// A requested column is not in the trace.
    UnknownColumn {
        /// The SVG file that was to be written.
        path: PathBuf,
        /// The name asked for.
        name: String,
        /// The trace's column names.
        available: Vec<String>,
    },
    /// Drawing or writing the SVG failed.
    Draw {
        /// The SVG file.
        path: PathBuf,
        /// What plotters said.
        message: String,
    },
}

impl fmt::Display for PlotError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            PlotError::EmptyTrace { path } => {
                write!(
                    f,
                    "{}: cannot plot: the trace has no samples",
                    path.display()
                )
            }
            PlotError::NoForces { path } => write!(
                f,
                "{}: cannot plot forces: the trace has no force columns",
                path.display()
            ),
            PlotError::NoColumns { path } => {
                write!(f, "{}: cannot plot: no columns were named", path.display())
            }
            PlotError::UnknownColumn {
                path,
                name,
                available,
            } => write!(
                f,
                "{}: cannot plot column `{name}`: the trace has no such column (columns: {})",
                path.display(),
                available.join(", ")
            ),
            PlotError::Draw { path, message } => {
                write!(f, "{}: cannot write plot: {message}", path.display())
            }
        }
    }
}

impl std::error::Error for PlotError {}

/// Writes an SVG with two panels: (top) every [`ColumnKind::Force`] column and the
/// [`ColumnKind::TotalForce`] column (newtons) vs time (ms), one coloured line each with a
/// legend, the total in black; (bottom) the total force vs the first [`ColumnKind::Sensor`]
/// column (key travel in mm) — the force–displacement loop. Without a total-force column the
/// sum of the force columns is used; without a sensor column the bottom panel is left out.
///
/// # Errors
///
/// [`PlotError::EmptyTrace`], [`PlotError::NoForces`], or [`PlotError::Draw`] when the file
/// cannot be written; every error names `path`.
pub fn plot_forces(trace: &Trace, title: &str, path: &Path) -> Result<(), PlotError> {
    let rows = trace.len();
    if rows == 0 {
        return Err(PlotError::EmptyTrace {
            path: path.to_path_buf(),
        });
    }
    let forces: Vec<&Column> = trace.columns_of(ColumnKind::Force).collect();
    let total_column = trace.columns_of(ColumnKind::TotalForce).next();
    if forces.is_empty() && total_column.is_none() {
        return Err(PlotError::NoForces {
            path: path.to_path_buf(),
        });
    }
    let time_ms: Vec<f64> = trace.times_s().iter().map(|t| t * 1e3).collect();
    let (total_name, total): (String, Vec<f64>) = match total_column {
        Some(c) => (c.name.clone(), c.values[..rows].to_vec()),
        None => (
            "sum of forces".to_string(),
            (0..rows)
                .map(|i| forces.iter().map(|c| c.values[i]).sum())
                .collect(),
        ),
    };

    let mut series: Vec<Series> = forces
        .iter()
        .enumerate()
        .map(|(i, c)| Series {
            label: c.name.clone(),
            x: &time_ms,
            y: c.values[..rows].to_vec(),
            colour: colour(i),
            width: 1,
        })
        .collect();
    series.push(Series {
        label: total_name.clone(),
        x: &time_ms,
        y: total.clone(),
        colour: BLACK.to_rgba(),
        width: 2,
    });

    let sensor = trace.columns_of(ColumnKind::Sensor).next();
    let height = if sensor.is_some() { 1000 } else { 560 };
    let draw = |root: DrawingArea<SVGBackend, Shift>| -> Result<(), String> {
        root.fill(&WHITE).map_err(|e| e.to_string())?;
        let root = root
            .titled(title, ("sans-serif", 22))
            .map_err(|e| e.to_string())?;
        match sensor {
            None => panel(&root, "forces", "time [ms]", "force [N]", &series)?,
            Some(sensor) => {
                let (top, bottom) = root.split_vertically(470);
                panel(&top, "forces", "time [ms]", "force [N]", &series)?;
                let (scale, unit) = display_unit(&sensor.unit);
                let key: Vec<f64> = sensor.values[..rows].iter().map(|v| v * scale).collect();
                let x_desc = axis_label(&sensor.name, unit);
                let caption = format!("{total_name} vs {}", sensor.name);
                let loop_series = [Series {
                    label: total_name.clone(),
                    x: &key,
                    y: total.clone(),
                    colour: BLACK.to_rgba(),
                    width: 1,
                }];
                panel(&bottom, &caption, &x_desc, "force [N]", &loop_series)?;
            }
        }
        root.present().map_err(|e| e.to_string())
    };
    draw(SVGBackend::new(path, (WIDTH, height)).into_drawing_area()).map_err(|message| {
        PlotError::Draw {
            path: path.to_path_buf(),
            message,
        }
    })
}

/// Writes an SVG of the named columns vs time (ms), one panel per column, in the order
/// given (e.g. hammer position and velocity). Values are shown in display units (m → mm,
/// s → ms). [`ColumnKind::Event`] columns are drawn as markers where the event fired.
///
/// # Errors
///
/// [`PlotError::NoColumns`], [`PlotError::UnknownColumn`] (listing the trace's columns),
/// [`PlotError::EmptyTrace`], or [`PlotError::Draw`]; every error names `path`.
pub fn plot_columns(
    trace: &Trace,
    names: &[&str],
    title: &str,
    path: &Path,
) -> Result<(), PlotError> {
    if names.is_empty() {
        return Err(PlotError::NoColumns {
            path: path.to_path_buf(),
        });
    }
    let mut columns = Vec::with_capacity(names.len());
    for name in names {
        match trace.column(name) {
            Some(c) => columns.push(c),
            None => {
                return Err(PlotError::UnknownColumn {
                    path: path.to_path_buf(),
                    name: name.to_string(),
                    available: trace.columns.iter().map(|c| c.name.clone()).collect(),
                })
            }
        }
    }
    let rows = trace.len();
    if rows == 0 {
        return Err(PlotError::EmptyTrace {
            path: path.to_path_buf(),
        });
    }
    let time_ms: Vec<f64> = trace.times_s().iter().map(|t| t * 1e3).collect();
    let height = 60 + 300 * columns.len() as u32;
    let draw = |root: DrawingArea<SVGBackend, Shift>| -> Result<(), String> {
        root.fill(&WHITE).map_err(|e| e.to_string())?;
        let root = root
            .titled(title, ("sans-serif", 22))
            .map_err(|e| e.to_string())?;
        let areas = root.split_evenly((columns.len(), 1));
        for (i, (area, column)) in areas.iter().zip(&columns).enumerate() {
            let (scale, unit) = display_unit(&column.unit);
            let series = [Series {
                label: column.name.clone(),
                x: &time_ms,
                y: column.values[..rows].iter().map(|v| v * scale).collect(),
                colour: colour(i),
                width: 1,
            }];
            let y_desc = axis_label(&column.name, unit);
            if column.kind == ColumnKind::Event {
                events_panel(area, &column.name, &y_desc, &series[0])?;
            } else {
                panel(area, &column.name, "time [ms]", &y_desc, &series)?;
            }
        }
        root.present().map_err(|e| e.to_string())
    };
    draw(SVGBackend::new(path, (WIDTH, height)).into_drawing_area()).map_err(|message| {
        PlotError::Draw {
            path: path.to_path_buf(),
            message,
        }
    })
}

/// One line of a passage plot: `y[i]` at `x[i]`, already in the units of the axes.
#[derive(Clone, Debug, PartialEq)]
pub struct Line {
    /// Legend label.
    pub label: String,
    /// Abscissae (e.g. time in seconds).
    pub x: Vec<f64>,
    /// Ordinates; `NaN` breaks the line.
    pub y: Vec<f64>,
}

/// Writes an SVG with one panel of lines (e.g. the force on each traced key over a passage,
/// time in seconds), one colour per line with a legend; long lines are decimated as in
/// every plot here.
///
/// # Errors
///
/// [`PlotError::EmptyTrace`] when there are no lines or no finite point, or
/// [`PlotError::Draw`]; every error names `path`.
pub fn plot_lines(
    lines: &[Line],
    title: &str,
    x_desc: &str,
    y_desc: &str,
    path: &Path,
) -> Result<(), PlotError> {
    let any_point = lines.iter().any(|l| {
        l.x.iter()
            .zip(&l.y)
            .any(|(x, y)| x.is_finite() && y.is_finite())
    });
    if !any_point {
        return Err(PlotError::EmptyTrace {
            path: path.to_path_buf(),
        });
    }
    let series: Vec<Series> = lines
        .iter()
        .enumerate()
        .map(|(i, l)| Series {
            label: l.label.clone(),
            x: &l.x,
            y: l.y.clone(),
            colour: colour(i),
            width: 1,
        })
        .collect();
    let draw = |root: DrawingArea<SVGBackend, Shift>| -> Result<(), String> {
        root.fill(&WHITE).map_err(|e| e.to_string())?;
        let root = root
            .titled(title, ("sans-serif", 22))
            .map_err(|e| e.to_string())?;
        panel(&root, "", x_desc, y_desc, &series)?;
        root.present().map_err(|e| e.to_string())
    };
    draw(SVGBackend::new(path, (WIDTH, 560)).into_drawing_area()).map_err(|message| {
        PlotError::Draw {
            path: path.to_path_buf(),
            message,
        }
    })
}

/// A series of [`plot_points`]: measured points as markers, or a line through them (a
/// fit, a band's edge).
#[derive(Clone, Debug)]
pub struct Points {
    /// The legend's label (empty: no legend entry).
    pub label: String,
    /// (x, y) in the axes' units; non-finite points, and on log axes non-positive ones,
    /// are left out.
    pub points: Vec<(f64, f64)>,
    /// Markers (measured points) or a line (a fit).
    pub line: bool,
    /// Dashed grey (a band's edge) instead of the series' colour.
    pub faint: bool,
}

/// Points and lines on one panel, linear or log–log axes (`log`), with a legend: a
/// measured sweep against a published fit and its band.
///
/// # Errors
///
/// [`PlotError::EmptyTrace`] without a point to draw, [`PlotError::Draw`] when the file
/// cannot be written.
pub fn plot_points(
    series: &[Points],
    title: &str,
    x_desc: &str,
    y_desc: &str,
    log: bool,
    path: &Path,
) -> Result<(), PlotError> {
    let keep =
        |&(x, y): &(f64, f64)| x.is_finite() && y.is_finite() && (!log || (x > 0.0 && y > 0.0));
    let kept: Vec<Vec<(f64, f64)>> = series
        .iter()
        .map(|s| s.points.iter().copied().filter(keep).collect())
        .collect();
    if kept.iter().all(Vec::is_empty) {
        return Err(PlotError::EmptyTrace {
            path: path.to_path_buf(),
        });
    }
    let all = || kept.iter().flatten();
    let range = |v: Vec<f64>| -> Range<f64> {
        if log {
            let lo = v.iter().copied().fold(f64::INFINITY, f64::min);
            let hi = v.iter().copied().fold(f64::NEG_INFINITY, f64::max);
            (lo / 1.2)..(hi * 1.2).max(lo * 1.5)
        } else {
            padded_range(v.into_iter())
        }
    };
    let (xr, yr) = (
        range(all().map(|p| p.0).collect()),
        range(all().map(|p| p.1).collect()),
    );
    let draw = |root: DrawingArea<SVGBackend, Shift>| -> Result<(), String> {
        root.fill(&WHITE).map_err(|e| e.to_string())?;
        let root = root
            .titled(title, ("sans-serif", 20))
            .map_err(|e| e.to_string())?;
        let mut builder = ChartBuilder::on(&root);
        builder
            .margin(12)
            .x_label_area_size(45)
            .y_label_area_size(70);
        macro_rules! body {
            ($chart:expr) => {{
                let mut chart = $chart.map_err(|e| e.to_string())?;
                draw_mesh(&mut chart, x_desc, y_desc)?;
                for (i, (s, pts)) in series.iter().zip(&kept).enumerate() {
                    let colour = if s.faint {
                        RGBColor(150, 150, 150).to_rgba()
                    } else {
                        colour(i)
                    };
                    let drawn = if s.line {
                        let style = ShapeStyle::from(colour).stroke_width(2);
                        if s.faint {
                            chart.draw_series(DashedLineSeries::new(
                                pts.iter().copied(),
                                6,
                                4,
                                style,
                            ))
                        } else {
                            chart.draw_series(LineSeries::new(pts.iter().copied(), style))
                        }
                    } else {
                        chart.draw_series(
                            pts.iter()
                                .map(|&p| Circle::new(p, 4, ShapeStyle::from(colour).filled())),
                        )
                    }
                    .map_err(|e| e.to_string())?;
                    if !s.label.is_empty() {
                        let line = s.line;
                        drawn.label(legend_label(&s.label)).legend(move |(x, y)| {
                            if line {
                                PathElement::new(
                                    vec![(x, y), (x + 24, y)],
                                    ShapeStyle::from(colour).stroke_width(2),
                                )
                                .into_dyn()
                            } else {
                                Circle::new((x + 12, y), 4, ShapeStyle::from(colour).filled())
                                    .into_dyn()
                            }
                        });
                    }
                }
                chart
                    .configure_series_labels()
                    .position(SeriesLabelPosition::UpperRight)
                    .label_font(("sans-serif", 14))
                    .background_style(WHITE.mix(0.85))
                    .border_style(BLACK)
                    .draw()
                    .map_err(|e| e.to_string())?;
            }};
        }
        if log {
            body!(builder.build_cartesian_2d(xr.clone().log_scale(), yr.clone().log_scale()));
        } else {
            body!(builder.build_cartesian_2d(xr.clone(), yr.clone()));
        }
        root.present().map_err(|e| e.to_string())
    };
    draw(SVGBackend::new(path, (WIDTH, 620)).into_drawing_area()).map_err(|message| {
        PlotError::Draw {
            path: path.to_path_buf(),
            message,
        }
    })
}

/// The lines of [`plot_cycle_series`]: one per series, its point `i` at `from_s + i /
/// sample_rate_hz` s, and the deadline across them; `None` without points or with a rate
/// that is not positive.
pub fn cycle_lines(
    cycles: &[(String, &[u64])],
    sample_rate_hz: f64,
    from_s: f64,
    deadline_cycles: u64,
) -> Option<Vec<Line>> {
    let samples = cycles.iter().map(|c| c.1.len()).max().unwrap_or(0);
    if samples == 0 || sample_rate_hz.is_nan() || sample_rate_hz <= 0.0 || !from_s.is_finite() {
        return None;
    }
    let at = |i: usize| from_s + i as f64 / sample_rate_hz;
    let mut lines: Vec<Line> = cycles
        .iter()
        .map(|(label, v)| Line {
            label: label.clone(),
            x: (0..v.len()).map(at).collect(),
            y: v.iter().map(|&n| n as f64).collect(),
        })
        .collect();
    lines.push(Line {
        label: format!("deadline ({deadline_cycles} cycles)"),
        x: vec![at(0), at(samples - 1)],
        y: vec![deadline_cycles as f64; 2],
    });
    Some(lines)
}

/// Cycles per sample over time, one named line per series (`("board 3", cycles)`, e.g. a
/// board's busier core), at `sample_rate_hz` points per second from `from_s` s (the time
/// of the first point: a play run's lead-in starts before the performance's 0 s), against
/// the per-sample deadline `deadline_cycles` ([`cycle_lines`]).
///
/// # Errors
///
/// [`PlotError::EmptyTrace`] without points, [`PlotError::Draw`] when the file cannot be
/// written.
pub fn plot_cycle_series(
    cycles: &[(String, &[u64])],
    sample_rate_hz: f64,
    from_s: f64,
    deadline_cycles: u64,
    title: &str,
    path: &Path,
) -> Result<(), PlotError> {
    let lines = cycle_lines(cycles, sample_rate_hz, from_s, deadline_cycles).ok_or_else(|| {
        PlotError::EmptyTrace {
            path: path.to_path_buf(),
        }
    })?;
    let path_buf = path.to_path_buf();
    let series: Vec<Series> = lines
        .iter()
        .enumerate()
        .map(|(i, l)| Series {
            label: l.label.clone(),
            x: &l.x,
            y: l.y.clone(),
            colour: if i + 1 == lines.len() {
                RGBColor(214, 39, 40).to_rgba()
            } else {
                colour(i)
            },
            width: if i + 1 == lines.len() { 2 } else { 1 },
        })
        .collect();
    let draw = |root: DrawingArea<SVGBackend, Shift>| -> Result<(), String> {
        root.fill(&WHITE).map_err(|e| e.to_string())?;
        let root = root
            .titled(title, ("sans-serif", 22))
            .map_err(|e| e.to_string())?;
        panel(&root, "cycles per sample", "time [s]", "cycles", &series)?;
        root.present().map_err(|e| e.to_string())
    };
    draw(SVGBackend::new(path, (WIDTH, 560)).into_drawing_area()).map_err(|message| {
        PlotError::Draw {
            path: path_buf,
            message,
        }
    })
}

/// The factor and unit to show an SI quantity in: metres as millimetres, seconds as
/// milliseconds, anything else as it is.
pub fn display_unit(si_unit: &str) -> (f64, &str) {
    match si_unit {
        "m" => (1e3, "mm"),
        "s" => (1e3, "ms"),
        other => (1.0, other),
    }
}

/// `name [unit]`, or `name` for a dimensionless quantity.
fn axis_label(name: &str, unit: &str) -> String {
    if unit.is_empty() {
        name.to_string()
    } else {
        format!("{name} [{unit}]")
    }
}

/// One line of a panel: points `(x[i], y[i])`, already in display units.
struct Series<'a> {
    label: String,
    x: &'a [f64],
    y: Vec<f64>,
    colour: RGBAColor,
    width: u32,
}

impl Series<'_> {
    /// Runs of consecutive finite points, each decimated to the minimum and maximum of
    /// every `bucket` samples (see the module documentation).
    fn runs(&self) -> Vec<Vec<(f64, f64)>> {
        let n = self.x.len().min(self.y.len());
        let bucket = n.div_ceil(MAX_POINTS_PER_SERIES / 2).max(1);
        let finite = |i: usize| self.x[i].is_finite() && self.y[i].is_finite();
        let mut runs = Vec::new();
        let mut i = 0;
        while i < n {
            while i < n && !finite(i) {
                i += 1;
            }
            let start = i;
            while i < n && finite(i) {
                i += 1;
            }
            if start < i {
                runs.push(self.decimate(start, i, bucket));
            }
        }
        runs
    }

    /// Points `start..end` (all finite): the lowest and the highest of each `bucket`
    /// samples, in time order.
    fn decimate(&self, start: usize, end: usize, bucket: usize) -> Vec<(f64, f64)> {
        let mut out = Vec::with_capacity(2 * (end - start).div_ceil(bucket));
        let mut b0 = start;
        while b0 < end {
            let b1 = (b0 + bucket).min(end);
            let (mut lo, mut hi) = (b0, b0);
            for i in b0..b1 {
                if self.y[i] < self.y[lo] {
                    lo = i;
                }
                if self.y[i] > self.y[hi] {
                    hi = i;
                }
            }
            let (a, b) = if lo <= hi { (lo, hi) } else { (hi, lo) };
            out.push((self.x[a], self.y[a]));
            if b != a {
                out.push((self.x[b], self.y[b]));
            }
            b0 = b1;
        }
        out
    }
}

/// The range of the finite values, padded by 5 % (at least ±0.5 around a constant).
fn padded_range(values: impl Iterator<Item = f64>) -> Range<f64> {
    let (lo, hi) = values
        .filter(|v| v.is_finite())
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), v| {
            (lo.min(v), hi.max(v))
        });
    if lo > hi {
        return 0.0..1.0;
    }
    // Values near ±f64::MAX would make the width and the padding overflow to ∞, on which
    // plotters' tick search never ends: the drawn range stops at ±MAX/4 (a line beyond it
    // is clipped), so width and padding stay finite.
    const LIMIT: f64 = f64::MAX / 4.0;
    let (lo, hi) = (lo.clamp(-LIMIT, LIMIT), hi.clamp(-LIMIT, LIMIT));
    let pad = if hi > lo {
        0.05 * (hi - lo)
    } else {
        0.5f64.max(0.05 * lo.abs())
    };
    (lo - pad)..(hi + pad)
}

/// Draws the mesh of every plot here: light grid lines, the axes' labels and their
/// descriptions `x_desc` and `y_desc`, in one style.
fn draw_mesh<X, Y, XT, YT>(
    chart: &mut ChartContext<'_, SVGBackend<'_>, Cartesian2d<X, Y>>,
    x_desc: &str,
    y_desc: &str,
) -> Result<(), String>
where
    X: Ranged<ValueType = XT> + ValueFormatter<XT>,
    Y: Ranged<ValueType = YT> + ValueFormatter<YT>,
{
    chart
        .configure_mesh()
        .x_desc(x_desc)
        .y_desc(y_desc)
        .label_style(("sans-serif", 13))
        .axis_desc_style(("sans-serif", 15))
        .light_line_style(RGBColor(235, 235, 235))
        .draw()
        .map_err(|e| e.to_string())
}

/// Draws one panel of line series with a mesh, axis descriptions and a legend.
fn panel(
    area: &DrawingArea<SVGBackend, Shift>,
    caption: &str,
    x_desc: &str,
    y_desc: &str,
    series: &[Series],
) -> Result<(), String> {
    let runs: Vec<Vec<Vec<(f64, f64)>>> = series.iter().map(Series::runs).collect();
    let points = || runs.iter().flatten().flatten();
    let x_range = padded_range(points().map(|p| p.0));
    let y_range = padded_range(points().map(|p| p.1));
    let mut chart = ChartBuilder::on(area)
        .caption(caption, ("sans-serif", 18))
        .margin(12)
        .x_label_area_size(45)
        .y_label_area_size(70)
        .build_cartesian_2d(x_range, y_range)
        .map_err(|e| e.to_string())?;
    draw_mesh(&mut chart, x_desc, y_desc)?;
    for (s, runs) in series.iter().zip(&runs) {
        let style = ShapeStyle::from(s.colour).stroke_width(s.width);
        for (k, run) in runs.iter().enumerate() {
            let drawn = chart
                .draw_series(LineSeries::new(run.iter().copied(), style))
                .map_err(|e| e.to_string())?;
            if k == 0 {
                let colour = s.colour;
                let width = s.width.max(2);
                drawn.label(legend_label(&s.label)).legend(move |(x, y)| {
                    PathElement::new(
                        vec![(x, y), (x + 24, y)],
                        ShapeStyle::from(colour).stroke_width(width),
                    )
                });
            }
        }
    }
    chart
        .configure_series_labels()
        .position(SeriesLabelPosition::UpperRight)
        .label_font(("sans-serif", 14))
        .background_style(WHITE.mix(0.85))
        .border_style(BLACK)
        .draw()
        .map_err(|e| e.to_string())
}

/// Draws an event column: a marker at every sample where the event fired (value not NaN).
fn events_panel(
    area: &DrawingArea<SVGBackend, Shift>,
    caption: &str,
    y_desc: &str,
    series: &Series,
) -> Result<(), String> {
    let fired: Vec<(f64, f64)> = series
        .x
        .iter()
        .zip(&series.y)
        .filter(|(x, y)| x.is_finite() && y.is_finite())
        .map(|(&x, &y)| (x, y))
        .collect();
    let x_range = padded_range(series.x.iter().copied());
    let y_range = padded_range(fired.iter().map(|p| p.1).chain([0.0]));
    let mut chart = ChartBuilder::on(area)
        .caption(caption, ("sans-serif", 18))
        .margin(12)
        .x_label_area_size(45)
        .y_label_area_size(70)
        .build_cartesian_2d(x_range, y_range)
        .map_err(|e| e.to_string())?;
    draw_mesh(&mut chart, "time [ms]", y_desc)?;
    let colour = series.colour;
    chart
        .draw_series(
            fired
                .iter()
                .map(|&p| Circle::new(p, 4, ShapeStyle::from(colour).filled())),
        )
        .map_err(|e| e.to_string())?
        .label(legend_label(&format!(
            "{} ({} fired)",
            series.label,
            fired.len()
        )))
        .legend(move |(x, y)| Circle::new((x + 12, y), 4, ShapeStyle::from(colour).filled()));
    chart
        .configure_series_labels()
        .position(SeriesLabelPosition::UpperRight)
        .label_font(("sans-serif", 14))
        .background_style(WHITE.mix(0.85))
        .border_style(BLACK)
        .draw()
        .map_err(|e| e.to_string())
}

/// Writes the trace columns `names` against time into one SVG: one panel with every series
/// when they share a unit (y label `a, b [unit]`, display units: m as mm), otherwise (or
/// with an event column) one panel per column, each labelled with its unit.
pub fn plot_named(
    trace: &Trace,
    names: &[String],
    title: &str,
    path: &std::path::Path,
) -> Result<(), String> {
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
        return plot_columns(trace, &refs, title, path).map_err(|e| e.to_string());
    }
    let (scale, shown) = display_unit(unit);
    let time_ms: Vec<f64> = trace.times_s().iter().map(|t| t * 1e3).collect();
    let lines: Vec<Line> = columns
        .iter()
        .map(|c| Line {
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
    plot_lines(&lines, title, "time [ms]", &y_desc, path).map_err(|e| e.to_string())
}

/// What [`plot_friction`] wrote: the CSV beside the SVG, and each `a` (s²/m²) with the
/// velocity of its extreme (m/s, [`tactus_runtime::friction::bilbao_peak_velocity`]).
#[derive(Clone, Debug)]
pub struct FrictionPlot {
    /// The curves as CSV: `v [m/s]`, then `phi(a=…)` per a.
    pub csv: PathBuf,
    /// Each a with the velocity of φ's positive extreme.
    pub peaks: Vec<(f64, f64)>,
}

/// `tactus plot friction`: Bilbao's friction characteristic φ(v, a) over [−v_max, v_max]
/// (m/s) for each `a` (s²/m²; [`tactus_runtime::friction::DEFAULT_A`] when empty), drawn to
/// the SVG `out` (its folder created) with the curves in a CSV beside it.
///
/// Errors: an `a` or `v_max` that is not finite and positive (naming the option), or a file
/// that cannot be written (naming it).
pub fn plot_friction(a: &[f64], v_max: f64, out: &Path) -> Result<FrictionPlot, String> {
    use std::fmt::Write as _;
    use tactus_runtime::friction;
    let a_values: Vec<f64> = if a.is_empty() {
        friction::DEFAULT_A.to_vec()
    } else {
        a.to_vec()
    };
    for &a in &a_values {
        if !(a.is_finite() && a > 0.0) {
            return Err(format!("--a {a}: must be finite and > 0 (s²/m²)"));
        }
    }
    if !(v_max.is_finite() && v_max > 0.0) {
        return Err(format!("--v-max {v_max}: must be finite and > 0 (m/s)"));
    }
    let v = friction::velocities(&a_values, v_max);
    let lines: Vec<Line> = a_values
        .iter()
        .map(|&a| Line {
            label: format!("a = {a} s²/m²"),
            x: v.clone(),
            y: v.iter().map(|&x| friction::bilbao_phi(x, a)).collect(),
        })
        .collect();
    if let Some(dir) = out.parent().filter(|d| !d.as_os_str().is_empty()) {
        std::fs::create_dir_all(dir)
            .map_err(|e| format!("cannot create `{}`: {e}", dir.display()))?;
    }
    plot_lines(
        &lines,
        "Bilbao's friction characteristic φ(v, a) = √(2a)·v·exp(−a·v² + ½)",
        "relative velocity v [m/s]",
        "φ(v, a)",
        out,
    )
    .map_err(|e| e.to_string())?;
    let csv = out.with_extension("csv");
    let mut text = String::from("v [m/s]");
    for a in &a_values {
        let _ = write!(text, ",phi(a={a})");
    }
    text.push('\n');
    for (i, x) in v.iter().enumerate() {
        let _ = write!(text, "{x}");
        for l in &lines {
            let _ = write!(text, ",{}", l.y[i]);
        }
        text.push('\n');
    }
    std::fs::write(&csv, text).map_err(|e| format!("{}: cannot write: {e}", csv.display()))?;
    Ok(FrictionPlot {
        csv,
        peaks: a_values
            .iter()
            .map(|&a| (a, friction::bilbao_peak_velocity(a)))
            .collect(),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A 0.3 s synthetic key press: a spring, a viscous term, an escapement-like bump, their
    /// total, a hammer state and an event.
    fn synthetic_trace() -> Trace {
        let fs = 44_100.0;
        let mut t = Trace::new(fs);
        t.add_column("t", "s", ColumnKind::Time);
        t.add_column("key", "m", ColumnKind::Sensor);
        t.add_column("spring", "N", ColumnKind::Force);
        t.add_column("viscous", "N", ColumnKind::Force);
        t.add_column("escapement", "N", ColumnKind::Force);
        t.add_column("total", "N", ColumnKind::TotalForce);
        t.add_column("hammer", "m", ColumnKind::State);
        t.add_column("strike", "m/s", ColumnKind::Event);
        let n = (0.3 * fs) as usize;
        let mut previous_key = 0.0;
        for i in 0..n {
            let time = i as f64 / fs;
            let u = (time / 0.15).min(2.0);
            let key = 0.005 * (1.0 - (std::f64::consts::PI * u).cos());
            let v = (key - previous_key) * fs;
            previous_key = key;
            let spring = 200.0 * key;
            let viscous = 5.0 * v;
            let escapement = if (0.006..0.008).contains(&key) && v > 0.0 {
                1.5
            } else {
                0.0
            };
            let total = spring + viscous + escapement;
            let hammer = 0.045 * (key / 0.01).powi(2);
            let strike = if i == n / 2 { 2.5 } else { f64::NAN };
            t.push_row(&[
                time, key, spring, viscous, escapement, total, hammer, strike,
            ])
            .unwrap();
        }
        t
    }

    fn temp_svg(tag: &str) -> PathBuf {
        std::env::temp_dir().join(format!("tactus-plot-{}-{tag}.svg", std::process::id()))
    }

    #[test]
    fn plot_forces_writes_an_svg_with_every_force_series() {
        let path = temp_svg("forces");
        plot_forces(&synthetic_trace(), "synthetic key", &path).unwrap();
        let svg = std::fs::read_to_string(&path).unwrap();
        std::fs::remove_file(&path).unwrap();
        assert!(svg.contains("<svg"));
        for label in [
            "synthetic key",
            "spring",
            "viscous",
            "escapement",
            "total",
            "time [ms]",
            "force [N]",
            "key [mm]",
        ] {
            assert!(svg.contains(label), "SVG lacks `{label}`");
        }
        // Decimated: four force series of 13 230 samples each would be far larger.
        assert!(svg.len() < 2_000_000, "SVG is {} bytes", svg.len());
    }

    #[test]
    fn plot_columns_writes_one_panel_per_column() {
        let path = temp_svg("columns");
        plot_columns(&synthetic_trace(), &["hammer", "strike"], "hammer", &path).unwrap();
        let svg = std::fs::read_to_string(&path).unwrap();
        std::fs::remove_file(&path).unwrap();
        assert!(svg.contains("<svg"));
        assert!(svg.contains("hammer [mm]"));
        assert!(svg.contains("strike [m/s]"));
        assert!(svg.contains("strike (1 fired)"));
    }

    #[test]
    fn errors_name_the_path() {
        let path = temp_svg("unknown");
        let e = plot_columns(&synthetic_trace(), &["nope"], "x", &path).unwrap_err();
        let msg = e.to_string();
        assert!(msg.contains(&*path.to_string_lossy()), "{msg}");
        assert!(msg.contains("`nope`") && msg.contains("hammer"), "{msg}");
        assert!(!path.exists());

        let e = plot_forces(&Trace::new(44_100.0), "x", &path).unwrap_err();
        assert!(matches!(e, PlotError::EmptyTrace { .. }));

        let bad = std::env::temp_dir()
            .join(format!("tactus-no-such-dir-{}", std::process::id()))
            .join("plot.svg");
        let e = plot_forces(&synthetic_trace(), "x", &bad).unwrap_err();
        assert!(matches!(e, PlotError::Draw { .. }), "{e}");
        assert!(e.to_string().contains("plot.svg"), "{e}");
    }

    #[test]
    fn nan_breaks_lines_and_decimation_keeps_peaks() {
        let x: Vec<f64> = (0..10).map(f64::from).collect();
        let s = Series {
            label: "s".into(),
            x: &x,
            y: vec![
                0.0,
                1.0,
                f64::NAN,
                3.0,
                4.0,
                5.0,
                f64::NAN,
                f64::NAN,
                8.0,
                9.0,
            ],
            colour: BLACK.to_rgba(),
            width: 1,
        };
        let runs = s.runs();
        assert_eq!(runs.len(), 3);
        assert_eq!(runs[1], vec![(3.0, 3.0), (4.0, 4.0), (5.0, 5.0)]);

        let n = 100_000;
        let x: Vec<f64> = (0..n).map(|i| i as f64).collect();
        let mut y = vec![0.0; n];
        y[54_321] = 7.0; // a one-sample spike
        let s = Series {
            label: "spike".into(),
            x: &x,
            y,
            colour: BLACK.to_rgba(),
            width: 1,
        };
        let runs = s.runs();
        let points: usize = runs.iter().map(Vec::len).sum();
        assert!(points <= MAX_POINTS_PER_SERIES, "{points} points");
        assert!(runs.iter().flatten().any(|&p| p == (54_321.0, 7.0)));
    }

    #[test]
    fn values_near_the_f64_limits_plot_in_bounded_time() {
        // Used to hang inside plotters: the padded range overflowed to ±∞.
        let mut trace = Trace::new(44_100.0);
        trace.add_column("time", "s", ColumnKind::Time);
        trace.add_column("key", "m", ColumnKind::Sensor);
        trace.add_column("f", "N", ColumnKind::Force);
        trace.add_column("total", "N", ColumnKind::TotalForce);
        for (i, f) in [f64::MAX, -f64::MAX, 1e300, f64::INFINITY, f64::NAN]
            .iter()
            .enumerate()
        {
            trace
                .push_row(&[i as f64, 1e-3 * i as f64, *f, *f])
                .unwrap();
        }
        let path = temp_svg("huge");
        let r = padded_range([f64::MAX, -f64::MAX].into_iter());
        assert!(r.start.is_finite() && r.end.is_finite() && (r.end - r.start).is_finite());
        plot_forces(&trace, "huge", &path).unwrap();
        assert!(std::fs::metadata(&path).unwrap().len() > 0);
    }

    #[test]
    fn plot_lines_and_cycles_per_core() {
        let path = temp_svg("lines");
        let lines = vec![
            Line {
                label: "key 60".into(),
                x: vec![0.0, 1.0, 2.0],
                y: vec![0.5, 3.0, 0.2],
            },
            Line {
                label: "key 64".into(),
                x: vec![0.5, 1.5],
                y: vec![1.0, f64::NAN],
            },
        ];
        plot_lines(&lines, "passage", "time [s]", "force [N]", &path).unwrap();
        let svg = std::fs::read_to_string(&path).unwrap();
        for label in ["passage", "key 60", "key 64", "force [N]", "time [s]"] {
            assert!(svg.contains(label), "SVG lacks `{label}`");
        }
        let e = plot_lines(&[], "x", "t", "y", &path).unwrap_err();
        assert!(matches!(e, PlotError::EmptyTrace { .. }), "{e}");

        // Synthetic cycle counts: core 0 under the deadline, core 1 over it once.
        let fs = 44_100.0;
        let core0: Vec<u64> = (0..10_000).map(|i| 1500 + (i % 7) as u64 * 10).collect();
        let mut core1: Vec<u64> = (0..10_000).map(|i| 2000 + (i % 5) as u64 * 20).collect();
        core1[5000] = 3400;
        let cpath = temp_svg("cycles");
        let named = [
            ("board 1".to_string(), core0.as_slice()),
            ("board 2".to_string(), core1.as_slice()),
        ];
        plot_cycle_series(&named, fs, 0.0, 2834, "budget", &cpath).unwrap();
        let svg = std::fs::read_to_string(&cpath).unwrap();
        std::fs::remove_file(&cpath).unwrap();
        std::fs::remove_file(&path).unwrap();
        for label in [
            "board 1",
            "board 2",
            "deadline (2834 cycles)",
            "cycles",
            "budget",
        ] {
            assert!(svg.contains(label), "SVG lacks `{label}`");
        }
        // One polyline per series and one for the deadline.
        assert!(svg.matches("<polyline").count() >= 3, "too few lines");
        let e = plot_cycle_series(&[], fs, 0.0, 100, "x", &cpath).unwrap_err();
        assert!(matches!(e, PlotError::EmptyTrace { .. }), "{e}");
        // From a lead-in of 441 samples: the first point at -10 ms, sample 441 at 0 s.
        let lines = cycle_lines(&named, fs, -0.01, 2834).unwrap();
        assert_eq!(lines[0].x[0], -0.01);
        assert!(lines[0].x[441].abs() < 1e-12, "{}", lines[0].x[441]);
        assert_eq!(lines[2].x, vec![-0.01, -0.01 + 9_999.0 / fs]);
    }
}
