//! The built-in pen gestures of contact-point instruments ([`gesture`], names in
//! [`gesture_names`]): the pen's penetration into the surface or string, its position along
//! the rubbing/bowing/plucking axis and, optionally, across; which sensors they drive is
//! [`pen_sensors`]. The convention follows the 3-DoF pen of Onofrei, Fontana & Serafin 2023
//! (plucking, bowing and rubbing physically-based resonators).

use super::sensor_stimulus::{positive, SensorStimulus, SensorStimulusError};
use super::GESTURES;
use crate::ir::Program;
use tactus_runtime::stimulus::MAX_SAMPLES;

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
