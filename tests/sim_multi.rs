//! Multi-sensor stimuli for contact-point instruments (`tactus_compiler::sim`): CSV files
//! naming the sensors, the built-in pen gestures, `tactus sim --plot` and
//! `tactus plot friction`. Driven through the `tactus` binary and the library; the
//! instruments are `rubbed_bank` and small pens written here, so debug runs stay short.

mod common;

use common::{assert_ok, tactus, temp_dir};
use std::path::Path;
use tactus_compiler::ir::Program;
use tactus_compiler::lower::Config;
use tactus_compiler::sim::{self, GestureConfig, SensorStimulus};
use tactus_runtime::stimulus;

const FS: f64 = 44_100.0;

/// A three-sensor pen with odd ranges (the press does not start at 0, the position is
/// centred on 0), a friction-free plane, the pen's velocity and its across position as
/// outputs.
const PEN3: &str = "// test pen, three sensors
instrument pen3 {
    sensor press: m in [2 mm, 4 mm]
    sensor pos: m in [-10 mm, 10 mm]
    sensor across: m in [0 mm, 30 mm]
    param k = 100 N/m
    force plane = k * press
    output vrel = d(pos)
    output side = across
}
";

/// A two-sensor pen whose stroke axis is only 5 mm long (every default stroke is clamped).
const PEN2: &str = "// test pen, two sensors, a short stroke axis
instrument pen2 {
    sensor press: m in [0 mm, 1 mm]
    sensor pos: m in [100 mm, 105 mm]
    force plane = 200 N/m * press
    output vrel = d(pos)
}
";

/// PEN3 as a vector sensor written in the order x, z, y: the gestures must find the depth
/// and the stroke by component, not by position.
const PENV: &str = "// test pen, a vector sensor out of the usual order
instrument penv {
    sensor pen: m in { x: [-10 mm, 10 mm], z: [2 mm, 4 mm], y: [0 mm, 30 mm] }
    param k = 100 N/m
    force contact = { z: k * pen.z }
    output vrel = d(pen.x)
    output side = pen.y
}
";

fn compile(src: &str) -> Program {
    tactus_compiler::compile(src, &Config::default())
        .unwrap_or_else(|d| {
            panic!(
                "{}",
                tactus_compiler::diagnostics::emit_to_string("test", src, &d)
            )
        })
        .program
}

fn rubbed_bank() -> Program {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("instruments/rubbed_bank.tactus");
    compile(&std::fs::read_to_string(path).unwrap())
}

/// Reads a trace CSV written by `tactus sim`: (header cells, columns of values; empty cells
/// as NaN).
fn read_csv(path: &Path) -> (Vec<String>, Vec<Vec<f64>>) {
    let text = std::fs::read_to_string(path).unwrap();
    let mut lines = text.lines();
    let header: Vec<String> = lines
        .next()
        .unwrap()
        .split(',')
        .map(str::to_string)
        .collect();
    let mut cols = vec![Vec::new(); header.len()];
    for l in lines {
        for (c, cell) in l.split(',').enumerate() {
            cols[c].push(if cell.is_empty() {
                f64::NAN
            } else {
                cell.parse().unwrap()
            });
        }
    }
    (header, cols)
}

fn col<'a>(csv: &'a (Vec<String>, Vec<Vec<f64>>), name: &str) -> &'a [f64] {
    let i = csv
        .0
        .iter()
        .position(|h| h == name)
        .unwrap_or_else(|| panic!("no column {name} in {:?}", csv.0));
    &csv.1[i]
}

fn write(dir: &Path, name: &str, text: &str) -> std::path::PathBuf {
    let f = dir.join(name);
    std::fs::write(&f, text).unwrap();
    f
}

/// A CSV naming both components of `rubbed_bank`'s vector sensor (trace-style headers with
/// units, times resampled) drives both: the trace's `pen.x` column follows the file (40 →
/// 60 mm while pressed 5 mm), and the friction (the force's x total) is zero before the
/// press and clearly non-zero while the pen rubs.
#[test]
fn multi_column_csv_drives_both_sensors_of_rubbed_bank() {
    let dir = temp_dir("multi-csv");
    let f = write(
        &dir,
        "rub.csv",
        "# press 5 mm, rub 20 mm at 0.1 m/s, lift\n\
         time [s],pen.z [m],pen.x [m]\n\
         0.00,0,0.040\n\
         0.02,0,0.040\n\
         0.04,0.005,0.040\n\
         0.24,0.005,0.060\n\
         0.26,0,0.060\n\
         0.30,0,0.060\n",
    );
    let out = tactus()
        .args(["sim", "rubbed_bank", "--stimulus"])
        .arg(&f)
        .arg("--out")
        .arg(&dir)
        .output()
        .unwrap();
    assert_ok(&out);
    let trace = read_csv(&dir.join("rubbed_bank-rub.csv"));
    let (t, press, rub, friction) = (
        col(&trace, "time [s]"),
        col(&trace, "pen.z [m]"),
        col(&trace, "pen.x [m]"),
        col(&trace, "force.x [N]"),
    );
    assert_eq!(t.len(), (0.30 * FS) as usize + 1);
    let at = |s: f64| (s * FS).round() as usize;
    assert!((rub[0] - 0.040).abs() < 1e-12 && (rub[at(0.29)] - 0.060).abs() < 1e-12);
    // Halfway through the rub: 50 mm, pressed 5 mm.
    assert!((rub[at(0.14)] - 0.050).abs() < 1e-6, "{}", rub[at(0.14)]);
    assert!((press[at(0.14)] - 0.005).abs() < 1e-12);
    assert!(
        friction[..at(0.02)].iter().all(|&f| f == 0.0),
        "friction before the press"
    );
    let rubbing = &friction[at(0.08)..at(0.22)];
    let mean_abs = rubbing.iter().map(|f| f.abs()).sum::<f64>() / rubbing.len() as f64;
    // The normal force is 1.5 N; the stick drags with a good part of it.
    assert!(
        mean_abs > 0.05,
        "mean |friction| while rubbing {mean_abs} N"
    );
}

/// Header cells without units and without a time column: one row per sample; sensors that
/// have no column read their lower bound; values outside a range are clamped with a note.
#[test]
fn csv_without_time_or_units_one_row_per_sample() {
    let p = compile(PEN3);
    let dir = temp_dir("multi-rows");
    let f = write(
        &dir,
        "rows.csv",
        "pos, press\n0.001, 0.003\n0.002, 0.009\n0.003, 0\n",
    );
    let s = sim::sensor_csv(&p, &f, FS).unwrap();
    assert_eq!(s.len(), 3);
    assert_eq!(s.sensors, ["press", "pos", "across"]);
    assert_eq!(s.row(0), [0.003, 0.001, 0.0]);
    assert_eq!(s.row(1), [0.004, 0.002, 0.0], "0.009 m clamped to 4 mm");
    assert_eq!(s.row(2), [0.002, 0.003, 0.0], "0 clamped to 2 mm");
    assert_eq!(s.notes.len(), 1, "{:?}", s.notes);
    assert!(
        s.notes[0].contains("2 readings of sensor `press`"),
        "{:?}",
        s.notes
    );

    // The old single-column key format still drives the first sensor, in millimetres.
    let k = write(&dir, "key.csv", "key_mm\n0\n3\n");
    let s = sim::sensor_csv(&p, &k, FS).unwrap();
    assert_eq!(s.row(1), [0.003, -0.010, 0.0]);
}

/// A column naming no sensor fails (exit code 1) with a message naming the file, the column
/// and the instrument's sensors; a malformed number names the line and the column; a
/// bracketed unit other than SI is refused.
#[test]
fn bad_csv_columns_are_clear_errors() {
    let dir = temp_dir("multi-bad");
    let unknown = write(
        &dir,
        "bow.csv",
        "time [s],pen.z [m],bow [m]\n0,0,0.04\n0.1,0.005,0.05\n",
    );
    let out = tactus()
        .args(["sim", "rubbed_bank", "--stimulus"])
        .arg(&unknown)
        .arg("--out")
        .arg(&dir)
        .output()
        .unwrap();
    assert_ne!(out.status.code(), Some(0));
    let err = String::from_utf8_lossy(&out.stderr);
    for part in [
        "bow.csv",
        "`bow [m]`",
        "rubbed_bank",
        "pen.z [m]",
        "pen.x [m]",
    ] {
        assert!(err.contains(part), "`{part}` missing from: {err}");
    }
    assert!(!err.contains("panicked"), "{err}");

    let p = rubbed_bank();
    let malformed = write(
        &dir,
        "bad.csv",
        "# a comment\ntime [s],pen.z [m],pen.x [m]\n0,0,0.04\n0.1,5 mm,0.05\n",
    );
    let e = sim::sensor_csv(&p, &malformed, FS).unwrap_err().to_string();
    assert!(
        e.contains("bad.csv:4") && e.contains("`pen.z [m]`") && e.contains("`5 mm`"),
        "{e}"
    );

    let mm = write(&dir, "mm.csv", "pen.z [mm],pen.x [m]\n5,0.04\n");
    let e = sim::sensor_csv(&p, &mm, FS).unwrap_err().to_string();
    assert!(e.contains("`pen.z [mm]`") && e.contains("[m]"), "{e}");

    let short = write(&dir, "short.csv", "pen.z,pen.x\n0.001\n");
    let e = sim::sensor_csv(&p, &short, FS).unwrap_err().to_string();
    assert!(e.contains("short.csv:2") && e.contains("1 cells"), "{e}");

    let back = write(&dir, "back.csv", "time,pen.x\n0,0.04\n0.1,0.05\n0.1,0.06\n");
    let e = sim::sensor_csv(&p, &back, FS).unwrap_err().to_string();
    assert!(e.contains("back.csv:4") && e.contains("increasing"), "{e}");
}

/// Peak |velocity| (m/s) and largest change of velocity between two samples (m/s) of one
/// channel, by finite differences.
fn speed_and_jerkiness(x: &[f64]) -> (f64, f64) {
    let v: Vec<f64> = x.windows(2).map(|w| (w[1] - w[0]) * FS).collect();
    let peak = v.iter().fold(0.0f64, |m, v| m.max(v.abs()));
    let dv = v.windows(2).fold(0.0f64, |m, w| m.max((w[1] - w[0]).abs()));
    (peak, dv)
}

/// Every gesture on both test pens: every reading inside its sensor's range, the press
/// reaching the requested depth (or its clamp), the stroke moving at the requested peak
/// speed, starting and ending at rest, smoothly (the velocity changes by less than 1 % of
/// the speed between samples: no steps for the differentiators); requests outside the
/// ranges are clamped and reported. A vector sensor's z, x and y are the depth, the stroke
/// and across whatever order they are written in.
#[test]
fn gestures_stay_inside_the_sensor_ranges() {
    assert_eq!(sim::pen_sensors(&compile(PEN3)), (0, 1, Some(2)));
    assert_eq!(sim::pen_sensors(&compile(PEN2)), (0, 1, None));
    assert_eq!(sim::pen_sensors(&compile(PENV)), (1, 0, Some(2)));
    for (src, config, want_notes) in [
        (PEN3, GestureConfig::default(), 0),
        (PENV, GestureConfig::default(), 0),
        (
            PENV,
            GestureConfig {
                depth_m: Some(0.050),
                speed_m_per_s: Some(0.3),
                stroke_m: Some(0.5),
                across_m: Some(-0.01),
            },
            3,
        ),
        (
            PEN3,
            GestureConfig {
                depth_m: Some(0.050),
                speed_m_per_s: Some(0.3),
                stroke_m: Some(0.5),
                across_m: Some(-0.01),
            },
            3,
        ),
        (PEN2, GestureConfig::default(), 1),
    ] {
        let p = compile(src);
        for (name, _) in sim::gesture_names() {
            let s = sim::gesture(&p, name, &config, FS).unwrap();
            let what = format!("{} {name} {config:?}", p.name);
            // PEN2's 5 mm stroke axis is shorter than the 20 mm default strokes of `press-rub`
            // and `pluck` (clamped, one note), not than `bow-stroke`'s 60 % of it.
            let notes = if src == PEN2 && *name == "bow-stroke" {
                0
            } else {
                want_notes
            };
            assert_eq!(s.notes.len(), notes, "{what}: {:?}", s.notes);
            for (i, sensor) in p.sensors.iter().enumerate() {
                let x = s.channel(i);
                let (lo, hi) = sensor.range;
                assert!(
                    x.iter().all(|v| (lo..=hi).contains(v)),
                    "{what}: sensor {} leaves [{lo}, {hi}]",
                    sensor.name
                );
            }
            let (iz, ix, iy) = sim::pen_sensors(&p);
            let lifted = p.sensors[iz].range.0;
            let press = s.channel(iz);
            let deepest = press.iter().fold(f64::MIN, |m, &v| m.max(v));
            let depth = config
                .depth_m
                .map_or(0.5 * (lifted + p.sensors[iz].range.1), |d| {
                    d.clamp(lifted, p.sensors[iz].range.1)
                });
            assert!((deepest - depth).abs() < 1e-12, "{what}: depth {deepest}");
            assert_eq!(press[0], lifted, "{what}: starts lifted");
            assert_eq!(press[s.len() - 1], lifted, "{what}: ends lifted");

            let pos = s.channel(ix);
            let speed = config
                .speed_m_per_s
                .unwrap_or(if *name == "pluck" { 0.2 } else { 0.1 });
            let (peak, dv) = speed_and_jerkiness(&pos);
            assert!(
                peak <= speed * 1.001 && peak > 0.9 * speed,
                "{what}: peak speed {peak} m/s, asked {speed}"
            );
            assert!(dv < 0.01 * speed, "{what}: velocity step {dv} m/s");
            let (_, dv_press) = speed_and_jerkiness(&press);
            assert!(dv_press < 0.005, "{what}: press velocity step {dv_press}");
            // The pen only moves along the stroke while pressed.
            for n in 1..s.len() {
                if pos[n] != pos[n - 1] {
                    assert!(press[n] > lifted, "{what}: moves lifted");
                }
            }
            if let Some(iy) = iy {
                let across = s.channel(iy);
                let want = config.across_m.map_or(0.0, |a| a.clamp(0.0, 0.030));
                assert!(across.iter().all(|&a| a == want), "{what}: across");
            }
        }
    }
    let one = compile(
        "instrument organ {\n    sensor key: m in [0 mm, 10 mm]\n    force k = 10 N/m * key\n}\n",
    );
    let e = sim::gesture(&one, "press-rub", &GestureConfig::default(), FS)
        .unwrap_err()
        .to_string();
    assert!(e.contains("`organ`") && e.contains("1 sensor (key)"), "{e}");
}

/// The CLI runs a gesture on a file instrument, warns about a clamped request, and the trace
/// stays inside the ranges; gesture options on a key stimulus are refused.
#[test]
fn sim_runs_gestures_from_the_cli() {
    let dir = temp_dir("multi-gesture");
    let pen = write(&dir, "pen3.tactus", PEN3);
    let out = tactus()
        .arg("sim")
        .arg(&pen)
        .args(["--stimulus", "pluck", "--depth", "9", "--speed", "0.25"])
        .arg("--out")
        .arg(&dir)
        .output()
        .unwrap();
    assert_ok(&out);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        err.contains("warning") && err.contains("clamped to 4.000 mm"),
        "{err}"
    );
    let trace = read_csv(&dir.join("pen3-pluck.csv"));
    let press = col(&trace, "press [m]");
    assert!(press.iter().all(|&x| (0.002..=0.004).contains(&x)));
    let vrel = col(&trace, "vrel [m/s]");
    let peak = vrel.iter().fold(0.0f64, |m, v| m.max(*v));
    assert!((peak - 0.25).abs() < 0.01, "d(pos) peaks at {peak} m/s");

    let bad = tactus()
        .arg("sim")
        .arg(&pen)
        .args(["--stimulus", "ff-dip", "--speed", "0.2"])
        .arg("--out")
        .arg(&dir)
        .output()
        .unwrap();
    assert_eq!(bad.status.code(), Some(1));
    assert!(String::from_utf8_lossy(&bad.stderr).contains("--speed applies to the pen gestures"));
}

/// A key stimulus on a two-sensor instrument drives the first sensor only: the second reads
/// its lower bound, and the key path is the same simulation as before multi-sensor stimuli.
#[test]
fn key_stimuli_drive_the_first_sensor_only() {
    let p = compile(PEN2);
    let key = stimulus::builtin("mf-dip", 0.001, FS).unwrap();
    let (trace, _) = sim::simulate(&p, &key);
    let pos = &trace.column("pos").unwrap().values;
    assert!(pos.iter().all(|&x| x == 0.100));
    let press = &trace.column("press").unwrap().values;
    assert!(press.contains(&0.001));
    let (again, _) = sim::simulate_sensors(&p, &SensorStimulus::from_key(&p, &key));
    assert_eq!(trace, again);
}

/// `--plot` draws the named columns into one SVG, y label with the trace's unit; an unknown
/// name fails before simulating, listing the columns there are.
#[test]
fn sim_plot_named_columns() {
    let dir = temp_dir("multi-plot");
    let pen = write(&dir, "pen3.tactus", PEN3);
    let out = tactus()
        .arg("sim")
        .arg(&pen)
        .args(["--stimulus", "press-rub", "--stroke", "5", "--plot", "vrel"])
        .arg("--out")
        .arg(&dir)
        .output()
        .unwrap();
    assert_ok(&out);
    let svg = std::fs::read_to_string(dir.join("pen3-press-rub-plot.svg")).unwrap();
    assert!(
        svg.contains("<svg") && svg.contains("vrel [m/s]"),
        "no labelled plot"
    );

    let bad = tactus()
        .arg("sim")
        .arg(&pen)
        .args([
            "--stimulus",
            "press-rub",
            "--plot",
            "vrel",
            "--plot",
            "vbow",
        ])
        .arg("--out")
        .arg(&dir)
        .output()
        .unwrap();
    assert_eq!(bad.status.code(), Some(1));
    let err = String::from_utf8_lossy(&bad.stderr);
    assert!(
        err.contains("`vbow`") && err.contains("vrel") && err.contains("plane"),
        "{err}"
    );
}

/// `tactus sim rubbed_bank --stimulus press-rub --plot force.x`: a pen instrument's trace has
/// its force's axis totals `force.x`, `force.y`, `force.z` where a keyboard's has `total`.
/// `force.z` is the plane (300 N/m · pen.z), `force.y` is 0 N (no term on y), and `force.x`
/// is the friction of the bank, recomputed here from the trace alone:
/// Σᵢ (k·z/11)·φ̂(√a·(vᵢ − v_r)), with vᵢ the masses' velocities of the previous row (the
/// trace records states after the dynamics), v_r = clamp(d(pen.x), ±1 m/s) from the
/// 8-sample differentiator on the `pen.x` column, and φ̂ the instrument's clamped
/// characteristic √2·u·exp(½ − u²). The summary prints each axis' range.
#[test]
fn sim_traces_the_pen_force_per_axis() {
    const K_PLANE: f64 = 300.0;
    const A: f64 = 100.0;
    let dir = temp_dir("multi-pen-axes");
    let out = tactus()
        .args(["sim", "rubbed_bank", "--stimulus", "press-rub"])
        .args(["--plot", "force.x", "--out"])
        .arg(&dir)
        .output()
        .unwrap();
    assert_ok(&out);
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(
        stdout.contains("force.x") && stdout.contains("force.y") && stdout.contains("force.z"),
        "{stdout}"
    );
    let svg = std::fs::read_to_string(dir.join("rubbed_bank-press-rub-plot.svg")).unwrap();
    assert!(svg.contains("force.x"), "no force.x in the plot");

    let trace = read_csv(&dir.join("rubbed_bank-press-rub.csv"));
    assert!(
        !trace.0.iter().any(|h| h.starts_with("total")),
        "{:?}",
        trace.0
    );
    for axis in ["force.x [N]", "force.y [N]", "force.z [N]"] {
        assert_eq!(trace.0.iter().filter(|h| *h == axis).count(), 1, "{axis}");
    }
    let (z, x) = (col(&trace, "pen.z [m]"), col(&trace, "pen.x [m]"));
    let (fx, fy, fz) = (
        col(&trace, "force.x [N]"),
        col(&trace, "force.y [N]"),
        col(&trace, "force.z [N]"),
    );
    let (cx, cz) = (col(&trace, "contact.x [N]"), col(&trace, "contact.z [N]"));
    let v: Vec<&[f64]> = (0..11)
        .map(|i| col(&trace, &format!("r[{i}].v [m/s]")))
        .collect();
    let (mut worst, mut peak) = (0.0f64, 0.0f64);
    for n in 0..x.len() {
        assert_eq!(fz[n], cz[n], "sample {n}: force.z is the one z term");
        assert!((fz[n] - K_PLANE * z[n]).abs() <= 1e-12, "sample {n}: plane");
        assert_eq!(fy[n], 0.0, "sample {n}: nothing on y");
        assert_eq!(fx[n], cx[n], "sample {n}: force.x is the one x term");
        // Before the first sample the differentiator's history is the first reading.
        let vr = ((x[n] - x[n.saturating_sub(8)]) * FS / 8.0).clamp(-1.0, 1.0);
        let normal = K_PLANE * z[n] / 11.0;
        let want: f64 = v
            .iter()
            .map(|vi| {
                let vi = if n == 0 { 0.0 } else { vi[n - 1] };
                let u = (A.sqrt() * (vi - vr)).clamp(-5.0, 5.0);
                let phi = std::f64::consts::SQRT_2 * u * (0.5 - u * u).exp();
                normal * phi.clamp(-1.0, 1.0)
            })
            .sum();
        worst = worst.max((fx[n] - want).abs());
        peak = peak.max(want.abs());
    }
    println!("force.x: peak {peak:.4} N, max |trace − recomputed| {worst:.2e} N");
    assert!(peak > 0.1, "the rub produced no friction: {peak} N");
    assert!(
        worst <= 1e-9 * peak,
        "force.x departs from the friction by {worst} N"
    );
    // The traces are about 47 MB: a passing run leaves nothing behind.
    let _ = std::fs::remove_dir_all(&dir);
}

/// Bilbao's characteristic, computed here independently of the binary.
fn phi(v: f64, a: f64) -> f64 {
    (2.0 * a).sqrt() * v * (0.5 - a * v * v).exp()
}

/// `tactus plot friction` writes the SVG and the CSV of its curves; each curve is φ(v, a)
/// and, where 1/√(2a) is inside ±0.5 m/s, peaks there at 1 (and at −1 mirrored); the
/// slippery a = 0.01 rises monotonically to the edge of the range.
#[test]
fn plot_friction_peaks_at_one_over_root_2a() {
    let dir = temp_dir("multi-friction");
    let svg = dir.join("sub").join("friction.svg");
    let out = tactus()
        .args(["plot", "friction", "-o"])
        .arg(&svg)
        .output()
        .unwrap();
    assert_ok(&out);
    let text = std::fs::read_to_string(&svg).unwrap();
    assert!(text.contains("<svg") && text.contains("a = 15000"), "SVG");
    let csv = read_csv(&svg.with_extension("csv"));
    let v = col(&csv, "v [m/s]");
    assert!(v.len() > 1000 && v[0] == -0.5 && v[v.len() - 1] == 0.5);
    for a in [0.01, 1.0, 100.0, 15000.0] {
        let y = col(&csv, &format!("phi(a={a})"));
        for (x, f) in v.iter().zip(y) {
            assert!((f - phi(*x, a)).abs() < 1e-12, "a = {a}, v = {x}: {f}");
        }
        let (imax, imin) = (0..v.len()).fold((0, 0), |(hi, lo), i| {
            (
                if y[i] > y[hi] { i } else { hi },
                if y[i] < y[lo] { i } else { lo },
            )
        });
        let peak = 1.0 / (2.0 * a).sqrt();
        if peak < 0.5 {
            assert!((v[imax] - peak).abs() < 1e-9, "a = {a}: max at {}", v[imax]);
            assert!((y[imax] - 1.0).abs() < 1e-12, "a = {a}: max {}", y[imax]);
            assert!((v[imin] + peak).abs() < 1e-9 && (y[imin] + 1.0).abs() < 1e-12);
        } else {
            assert_eq!(v[imax], 0.5, "a = {a}");
            assert!(y[imax] < 1.0);
        }
    }

    let custom = dir.join("four.svg");
    let out = tactus()
        .args(["plot", "friction", "--a", "4", "-o"])
        .arg(&custom)
        .output()
        .unwrap();
    assert_ok(&out);
    let csv = read_csv(&custom.with_extension("csv"));
    let (v, y) = (col(&csv, "v [m/s]"), col(&csv, "phi(a=4)"));
    let imax = (0..v.len()).fold(0, |m, i| if y[i] > y[m] { i } else { m });
    assert!((v[imax] - 1.0 / 8f64.sqrt()).abs() < 1e-9 && (y[imax] - 1.0).abs() < 1e-12);

    let bad = tactus()
        .args(["plot", "friction", "--a", "-1", "-o"])
        .arg(&custom)
        .output()
        .unwrap();
    assert_eq!(bad.status.code(), Some(1));
    assert!(String::from_utf8_lossy(&bad.stderr).contains("--a -1"));
}
